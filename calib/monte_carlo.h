// The Monte Carlo check of a calibration's GUM budget (JCGM 101): the calibrated angle's distribution drawn, its 95 % interval against U.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/calibrator.h"

namespace fpss {

// One axis at the listed angle of the largest expanded uncertainty (the budget's angle).
struct MonteCarloAxis {
  std::string axis;
  double angle_arcsec = 0;
  double mean_arcsec = 0, u_arcsec = 0;  // of (calibrated - true angle) over the trials
  double low_arcsec = 0, high_arcsec = 0;  // the probabilistically symmetric 95 % coverage interval
  double gum_u_arcsec = 0, gum_expanded_arcsec = 0;  // the budget's u and U (interval -U..U about 0)
  // JCGM 101 section 8: d_low = |-U - low|, d_high = |U - high|, against the numerical tolerance
  // delta of the GUM u written to two significant digits (u = c 10^l: delta = 10^l / 2).
  double d_low_arcsec = 0, d_high_arcsec = 0, tolerance_arcsec = 0;
  bool gum_validated = false;
};

struct MonteCarloCheck {
  size_t trials = 0;
  uint64_t seed = 0;
  std::vector<MonteCarloAxis> axes;  // pitch, yaw (an axis without a budget is left out)
  nlohmann::ordered_json to_json() const;
};

// Draws `trials` errors of the calibrated angle at the budget's angle: each of the fit's sources
// (AxisFit::covariance_sources) with its standard uncertainty there, as Student's t for finite
// degrees of freedom (JCGM 101 6.4.9), to first order in the coefficients (their covariance is a
// linearisation: drawn whole they leave the region where it holds); each term of the reference's
// calibration from N(value, u), through the reference's error model itself (nonlinear in the
// cyclic terms and the non-orthogonality). It checks the Welch-Satterthwaite coverage factor and
// the reference's linearisation.
// std::invalid_argument for trials < 100 or more than 10^7 (80 MB of draws per axis).
MonteCarloCheck monte_carlo_check(const CalibrationReport& rep, const CalibrationOptions& opts, size_t trials,
                                  uint64_t seed = 1);

// The check's lines for the calibrate summary.
std::string monte_carlo_text(const MonteCarloCheck& mc);

}  // namespace fpss
