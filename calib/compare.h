// Difference B - A of two calibrations' transfer functions at equal counts (the paper's Figures 1 and 2).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"

namespace fpss {

inline constexpr double kDefaultCompareRangeDeg = 0.35;  // the paper's calibrated range (Table 1, V and VI)

// One axis: B(N) - A(N) at every integer count N whose angle under A lies within +-range.
struct AxisComparison {
  std::string axis;               // "alpha" or "beta"
  int64_t lo_counts = 0, hi_counts = 0;  // the counts A maps into +-range (one contiguous run)
  double mean_arcsec = 0;         // the mean difference: a null shift between the two
  double max_abs_arcsec = 0;
  double rms_arcsec = 0;
  double max_abs_offset_removed_arcsec = 0;  // max |d - mean|: the change of shape
  int64_t at_counts = 0;          // where |d| is largest
  // The curve (for plots): counts, angle under A, difference; thinned to at most ~2000 points.
  std::vector<double> counts, angle_a_arcsec, diff_arcsec;
};

struct CalibrationComparison {
  double range_deg = kDefaultCompareRangeDeg;
  AxisComparison alpha, beta;

  // Exactly {"alpha": {"max_abs_arcsec", "rms_arcsec", "max_abs_offset_removed_arcsec"}, "beta": {...}}.
  nlohmann::ordered_json summary_json() const;
  // The summary plus counts range, mean and where the maximum is, per axis.
  nlohmann::ordered_json detail_json() const;
};

// The counts around A's null (the count where |A| is smallest) that A maps into +-range_arcsec,
// as the largest contiguous run of integer counts within the sensor's range. Throws DataError
// when A does not reach inside +-range anywhere.
std::pair<int64_t, int64_t> counts_within(const AxisModel& a, double range_arcsec);

// Throws InputError for a range that is not positive and finite.
AxisComparison compare_axis(const AxisModel& a, const AxisModel& b, double range_deg, const std::string& axis);
CalibrationComparison compare_calibrations(const CoefficientSet& a, const CoefficientSet& b,
                                           double range_deg = kDefaultCompareRangeDeg);

// A readable table of the comparison: one row per axis, A and B named.
std::string comparison_table(const CalibrationComparison& c, const std::string& name_a, const std::string& name_b);

// Unit history: has the latest calibration moved from the previous one by more than a limit?
inline constexpr double kDefaultDriftLimitArcsec = 1.0;
struct DriftCheck {
  CalibrationComparison comparison;  // latest - previous over the previous one's +-range
  double worst_arcsec = 0;           // max of the two axes' max_abs
  double worst_shape_arcsec = 0;     // max of the two axes' max_abs_offset_removed
  double limit_arcsec = kDefaultDriftLimitArcsec;
  bool flagged = false;              // worst_arcsec > limit_arcsec
  std::string worst_axis;            // "alpha" or "beta"
};
DriftCheck check_drift(const CoefficientSet& previous, const CoefficientSet& latest,
                       double limit_arcsec = kDefaultDriftLimitArcsec,
                       double range_deg = kDefaultCompareRangeDeg);

}  // namespace fpss
