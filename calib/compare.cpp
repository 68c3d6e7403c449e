#include "calib/compare.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "base/errors.h"
#include "calib/units.h"

namespace fpss {
namespace {

constexpr size_t kPlotPoints = 2000;

nlohmann::ordered_json axis_summary(const AxisComparison& a) {
  nlohmann::ordered_json j;
  j["max_abs_arcsec"] = a.max_abs_arcsec;
  j["rms_arcsec"] = a.rms_arcsec;
  j["max_abs_offset_removed_arcsec"] = a.max_abs_offset_removed_arcsec;
  return j;
}

nlohmann::ordered_json axis_detail(const AxisComparison& a) {
  nlohmann::ordered_json j = axis_summary(a);
  j["mean_arcsec"] = a.mean_arcsec;
  j["at_counts"] = a.at_counts;
  j["counts_range"] = {a.lo_counts, a.hi_counts};
  return j;
}

}  // namespace

nlohmann::ordered_json CalibrationComparison::summary_json() const {
  nlohmann::ordered_json j;
  j["alpha"] = axis_summary(alpha);
  j["beta"] = axis_summary(beta);
  return j;
}

nlohmann::ordered_json CalibrationComparison::detail_json() const {
  nlohmann::ordered_json j;
  j["range_deg"] = range_deg;
  j["alpha"] = axis_detail(alpha);
  j["beta"] = axis_detail(beta);
  return j;
}

std::pair<int64_t, int64_t> counts_within(const AxisModel& a, double range_arcsec) {
  const auto lo = static_cast<int64_t>(kCountsMin), hi = static_cast<int64_t>(kCountsMax);
  // The null: where |A| is smallest. A scan of every count, not a root finder, so a set that is
  // not monotonic (a misprinted table) still gets a defined answer.
  int64_t best = lo;
  double best_abs = std::abs(a.angle_arcsec(static_cast<double>(lo)));
  for (int64_t n = lo + 1; n <= hi; ++n) {
    const double v = std::abs(a.angle_arcsec(static_cast<double>(n)));
    if (v < best_abs) {
      best_abs = v;
      best = n;
    }
  }
  if (best_abs > range_arcsec) {
    throw DataError(fmt::format("the transfer function never comes within +-{:.1f} arcsec of zero over counts "
                                "[{}, {}] (closest {:.1f} arcsec at N = {})",
                                range_arcsec, lo, hi, best_abs, best));
  }
  int64_t first = best, last = best;
  while (first > lo && std::abs(a.angle_arcsec(static_cast<double>(first - 1))) <= range_arcsec) --first;
  while (last < hi && std::abs(a.angle_arcsec(static_cast<double>(last + 1))) <= range_arcsec) ++last;
  return {first, last};
}

AxisComparison compare_axis(const AxisModel& a, const AxisModel& b, double range_deg, const std::string& axis) {
  if (!std::isfinite(range_deg) || range_deg <= 0) {
    throw InputError(fmt::format("compare: range must be a positive number of degrees, got {}", range_deg));
  }
  AxisComparison out;
  out.axis = axis;
  const auto [first, last] = counts_within(a, deg_to_arcsec(range_deg));
  out.lo_counts = first;
  out.hi_counts = last;
  const auto n = static_cast<size_t>(last - first + 1);
  std::vector<double> d(n);
  double sum = 0, sum2 = 0;
  for (size_t i = 0; i < n; ++i) {
    const double counts = static_cast<double>(first + static_cast<int64_t>(i));
    d[i] = rad_to_arcsec(b.angle_rad(counts) - a.angle_rad(counts));
    sum += d[i];
    sum2 += d[i] * d[i];
    if (std::abs(d[i]) > out.max_abs_arcsec) {
      out.max_abs_arcsec = std::abs(d[i]);
      out.at_counts = first + static_cast<int64_t>(i);
    }
  }
  out.mean_arcsec = sum / static_cast<double>(n);
  out.rms_arcsec = std::sqrt(sum2 / static_cast<double>(n));
  for (double v : d) out.max_abs_offset_removed_arcsec = std::max(out.max_abs_offset_removed_arcsec, std::abs(v - out.mean_arcsec));

  const size_t stride = (n + kPlotPoints - 1) / kPlotPoints;
  for (size_t i = 0; i < n; i += stride) {
    const double counts = static_cast<double>(first + static_cast<int64_t>(i));
    out.counts.push_back(counts);
    out.angle_a_arcsec.push_back(a.angle_arcsec(counts));
    out.diff_arcsec.push_back(d[i]);
  }
  if ((n - 1) % stride != 0) {  // always end on the last count
    out.counts.push_back(static_cast<double>(last));
    out.angle_a_arcsec.push_back(a.angle_arcsec(static_cast<double>(last)));
    out.diff_arcsec.push_back(d[n - 1]);
  }
  return out;
}

CalibrationComparison compare_calibrations(const CoefficientSet& a, const CoefficientSet& b, double range_deg) {
  CalibrationComparison c;
  c.range_deg = range_deg;
  c.alpha = compare_axis(a.alpha_model(), b.alpha_model(), range_deg, "alpha");
  c.beta = compare_axis(a.beta_model(), b.beta_model(), range_deg, "beta");
  return c;
}

std::string comparison_table(const CalibrationComparison& c, const std::string& name_a, const std::string& name_b) {
  std::string s = fmt::format("B - A at equal counts, over the counts A maps into +-{} deg\n  A: {}\n  B: {}\n\n", c.range_deg,
                              name_a, name_b);
  s += fmt::format("{:<6} {:>15} {:>12} {:>12} {:>12} {:>18}\n", "axis", "counts", "mean\"", "max|d|\"", "rms\"",
                   "max|d-mean|\"");
  for (const AxisComparison* a : {&c.alpha, &c.beta}) {
    s += fmt::format("{:<6} {:>15} {:>12.3f} {:>12.3f} {:>12.3f} {:>18.3f}\n", a->axis,
                     fmt::format("{}..{}", a->lo_counts, a->hi_counts), a->mean_arcsec, a->max_abs_arcsec,
                     a->rms_arcsec, a->max_abs_offset_removed_arcsec);
  }
  s += "(arcsec; mean = null shift between the two, max|d-mean| = change of shape)\n";
  return s;
}

DriftCheck check_drift(const CoefficientSet& previous, const CoefficientSet& latest, double limit_arcsec,
                       double range_deg) {
  if (!std::isfinite(limit_arcsec) || limit_arcsec <= 0) {
    throw InputError(fmt::format("drift limit must be a positive number of arcsec, got {}", limit_arcsec));
  }
  DriftCheck d;
  d.comparison = compare_calibrations(previous, latest, range_deg);
  d.limit_arcsec = limit_arcsec;
  const bool beta_worse = d.comparison.beta.max_abs_arcsec > d.comparison.alpha.max_abs_arcsec;
  d.worst_axis = beta_worse ? "beta" : "alpha";
  d.worst_arcsec = std::max(d.comparison.alpha.max_abs_arcsec, d.comparison.beta.max_abs_arcsec);
  d.worst_shape_arcsec =
      std::max(d.comparison.alpha.max_abs_offset_removed_arcsec, d.comparison.beta.max_abs_offset_removed_arcsec);
  d.flagged = d.worst_arcsec > limit_arcsec;
  return d;
}

}  // namespace fpss
