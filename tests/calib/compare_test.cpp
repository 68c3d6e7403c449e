// calib/compare: B - A at equal counts, checked against eq. 1 evaluated here with its own loop.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "base/errors.h"
#include "calib/compare.h"

namespace fpss {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kArcsec = 180.0 * 3600.0 / kPi;  // written out again, not taken from calib/units.h

// Eq. 1 of the paper, written out here rather than through calib/transfer_function.h.
double eq1(const AxisCoeffs& c, double n) {
  return c[0] + c[1] * n + c[2] * std::sin(c[3] * n + c[4]) + c[5] * std::sin(c[6] * n + c[7]);
}

struct Expected {
  long lo = 0, hi = 0;
  double max_abs = 0, rms = 0, mean = 0, max_abs_offset_removed = 0;
};

// Every integer count in the full 16-bit range whose angle under A is within +-range; the run
// around the null is checked to be the whole set (these sets are monotonic over the range).
Expected expected(const AxisCoeffs& a, const AxisCoeffs& b, double range_deg) {
  const double range_rad = range_deg * kPi / 180.0;
  Expected e;
  long count = 0;
  double sum = 0, sum2 = 0;
  e.lo = 100000;
  e.hi = -100000;
  for (long n = -32768; n <= 32767; ++n) {
    if (std::fabs(eq1(a, static_cast<double>(n))) > range_rad) continue;
    e.lo = std::min(e.lo, n);
    e.hi = std::max(e.hi, n);
    const double d = (eq1(b, static_cast<double>(n)) - eq1(a, static_cast<double>(n))) * kArcsec;
    ++count;
    sum += d;
    sum2 += d * d;
    e.max_abs = std::max(e.max_abs, std::fabs(d));
  }
  EXPECT_EQ(count, e.hi - e.lo + 1) << "the set is not one contiguous run";
  e.mean = sum / static_cast<double>(count);
  e.rms = std::sqrt(sum2 / static_cast<double>(count));
  for (long n = e.lo; n <= e.hi; ++n) {
    const double d = (eq1(b, static_cast<double>(n)) - eq1(a, static_cast<double>(n))) * kArcsec;
    e.max_abs_offset_removed = std::max(e.max_abs_offset_removed, std::fabs(d - e.mean));
  }
  return e;
}

void expect_axis(const AxisComparison& got, const Expected& want) {
  EXPECT_EQ(got.lo_counts, want.lo);
  EXPECT_EQ(got.hi_counts, want.hi);
  EXPECT_NEAR(got.max_abs_arcsec, want.max_abs, 1e-9);
  EXPECT_NEAR(got.rms_arcsec, want.rms, 1e-9);
  EXPECT_NEAR(got.mean_arcsec, want.mean, 1e-9);
  EXPECT_NEAR(got.max_abs_offset_removed_arcsec, want.max_abs_offset_removed, 1e-9);
}

TEST(Compare, PaperFpss1VAgainstViMatchesEq1) {
  const CoefficientSet v = load_published("a-6-fpss1");
  const CoefficientSet vi = load_published("a-7-fpss1");
  const CalibrationComparison c = compare_calibrations(v, vi, 0.35);
  expect_axis(c.alpha, expected(v.alpha, vi.alpha, 0.35));
  expect_axis(c.beta, expected(v.beta, vi.beta, 0.35));
  // What the paper's Figures 1 and 2 show: VI's alpha sits some 46 arcsec from V's (the +44
  // arcsec yaw slew of August 22 moved A1), and both axes changed shape by several arcsec.
  EXPECT_LT(c.alpha.mean_arcsec, -40.0);
  EXPECT_GT(c.alpha.max_abs_offset_removed_arcsec, 1.0);
  EXPECT_GT(c.beta.max_abs_offset_removed_arcsec, 1.0);
}

TEST(Compare, EveryPaperStepOfBothUnitsMatchesEq1) {
  const char* tables[] = {"a-1", "a-2", "a-3", "a-4", "a-5", "a-6", "a-7"};
  for (const char* unit : {"fpss1", "fpss2"}) {
    for (size_t i = 1; i < std::size(tables); ++i) {
      const CoefficientSet a = load_published(std::string(tables[i - 1]) + "-" + unit);
      const CoefficientSet b = load_published(std::string(tables[i]) + "-" + unit);
      SCOPED_TRACE(std::string(tables[i - 1]) + " -> " + tables[i] + " " + unit);
      const CalibrationComparison c = compare_calibrations(a, b, 0.25);
      expect_axis(c.alpha, expected(a.alpha, b.alpha, 0.25));
      expect_axis(c.beta, expected(a.beta, b.beta, 0.25));
    }
  }
}

TEST(Compare, IdenticalSetsDifferByNothingAndAShiftIsOnlyAnOffset) {
  const CoefficientSet v = load_published("a-6-fpss1");
  CalibrationComparison c = compare_calibrations(v, v);
  EXPECT_EQ(c.alpha.max_abs_arcsec, 0.0);
  EXPECT_EQ(c.beta.rms_arcsec, 0.0);

  CoefficientSet shifted = v;
  shifted.alpha[0] += 3.0 / kArcsec;  // a 3 arcsec null shift
  c = compare_calibrations(v, shifted);
  EXPECT_NEAR(c.alpha.max_abs_arcsec, 3.0, 1e-6);
  EXPECT_NEAR(c.alpha.rms_arcsec, 3.0, 1e-6);
  EXPECT_NEAR(c.alpha.mean_arcsec, 3.0, 1e-6);
  EXPECT_LT(c.alpha.max_abs_offset_removed_arcsec, 1e-6);
  EXPECT_EQ(c.beta.max_abs_arcsec, 0.0);
}

TEST(Compare, RangeFollowsTheFirstSetsNull) {
  // A moved by exactly +1000 counts (a(N) -> a(N - 1000)): the compared counts move with it.
  const CoefficientSet base = load_published("a-6-fpss2");
  CoefficientSet a = base;
  a.beta[0] -= a.beta[1] * 1000.0;
  a.beta[4] -= a.beta[3] * 1000.0;
  a.beta[7] -= a.beta[6] * 1000.0;
  const auto [lo0, hi0] = counts_within(base.beta_model(), 0.35 * 3600.0);
  const auto [lo1, hi1] = counts_within(a.beta_model(), 0.35 * 3600.0);
  EXPECT_EQ(lo1 - lo0, 1000);
  EXPECT_EQ(hi1 - hi0, 1000);
}

TEST(Compare, JsonHasExactlyTheContractKeys) {
  const CalibrationComparison c = compare_calibrations(load_published("a-6-fpss1"), load_published("a-7-fpss1"));
  const auto j = c.summary_json();
  ASSERT_EQ(j.size(), 2u);
  for (const char* axis : {"alpha", "beta"}) {
    ASSERT_TRUE(j.contains(axis));
    ASSERT_EQ(j[axis].size(), 3u);
    for (const char* key : {"max_abs_arcsec", "rms_arcsec", "max_abs_offset_removed_arcsec"}) {
      ASSERT_TRUE(j[axis][key].is_number()) << axis << "." << key;
    }
  }
}

TEST(Compare, BadRangeAndUnreachableRangeAreInputErrors) {
  const CoefficientSet v = load_published("a-6-fpss1");
  EXPECT_THROW(compare_calibrations(v, v, 0.0), InputError);
  EXPECT_THROW(compare_calibrations(v, v, -1.0), InputError);
  EXPECT_THROW(compare_calibrations(v, v, std::nan("")), InputError);
  CoefficientSet far = v;
  far.alpha[0] += 3.0 * kPi / 180.0;  // 3 deg off everywhere: never near zero
  EXPECT_THROW(compare_calibrations(far, v), DataError);
}

TEST(Compare, DriftFlagFollowsTheLimit) {
  const CoefficientSet v = load_published("a-6-fpss1");
  CoefficientSet moved = v;
  moved.beta[0] += 0.6 / kArcsec;
  DriftCheck d = check_drift(v, moved, 1.0);
  EXPECT_FALSE(d.flagged);
  EXPECT_NEAR(d.worst_arcsec, 0.6, 1e-6);
  EXPECT_EQ(d.worst_axis, "beta");
  d = check_drift(v, moved, 0.5);
  EXPECT_TRUE(d.flagged);
  d = check_drift(v, load_published("a-7-fpss1"));
  EXPECT_TRUE(d.flagged);
  EXPECT_EQ(d.worst_axis, "alpha");
  EXPECT_THROW(check_drift(v, v, 0.0), InputError);
}

}  // namespace
}  // namespace fpss
