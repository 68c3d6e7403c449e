// The calibration report as text (the paper's Table 1 and the coefficients) and as JSON blocks.
#pragma once
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "calib/calibrator.h"

namespace fpss {

// {"pitch": {"mean_abs_arcsec", "sd_arcsec", "max_abs_arcsec", "points", "range_deg": [lo, hi]}, "yaw": {...}}
nlohmann::json residuals_json(const CalibrationReport& r);
// Per axis: 1-sigma of C1..C8, of the angle over the range, and how the covariance was had.
nlohmann::json uncertainties_json(const CalibrationReport& r);
nlohmann::json solver_json(const CalibrationReport& r);

// Table-1-style summary, the coefficients with their 1-sigma and the solver outcome.
std::string summary_text(const CalibrationReport& r);
// The same summary's head (its first line, Table 1, the coefficients with their 1-sigma) from a
// fitted coefficient file (calibration.json: its residuals, dwells and uncertainties blocks), in the
// same form; "" for a set that is no fit (no residuals block: a published set).
std::string summary_text(const CoefficientSet& fitted);

// Per axis, how far the fit is from a known truth over the calibrated count range.
struct TruthComparison {
  TransferDifference pitch, yaw;
};
TruthComparison compare_to_truth(const CalibrationReport& r, const CoefficientSet& truth);
std::string truth_text(const TruthComparison& t, const std::string& truth_name);

}  // namespace fpss
