// The nonlinear refinement of one axis with Ceres, and its covariance: the one solver of eq. 1.
// Only refine.cpp and refine_gls.cpp include ceres.h, to keep the build cheap.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calib/residuals.h"

namespace fpss::fit {

struct RefineOptions {
  int max_iterations = 200;
  int threads = 1;
  int rows_per_block = 64;  // residuals per Ceres residual block: few blocks, little overhead
};

struct Refined {
  AxisCoeffs coeffs{};  // differences: C1 from the null condition; absolute: fitted
  double initial_cost = 0, final_cost = 0;  // Ceres cost, 0.5 * sum r^2, arcsec^2
  size_t rows = 0;  // rows used
  int iterations = 0;
  bool usable = false, converged = false;
  std::string brief;  // Ceres BriefReport
};

// How the sensor's temperature during the recording moves a GLS fit (GlsData::temperature_c): the
// fit is linear in the dwells' errors, so a reading that shifts by kappa (T_k - T_ref) arcsec moves
// the scaled coefficients by kappa x shift_scaled. kappa is estimated from the residuals by the GLS
// of them on the dwells' temperatures with the fit's columns projected out (what the coefficients
// did not absorb). Known when some dwells carry a temperature.
struct TemperatureInfluence {
  bool known = false;
  double reference_c = 0;  // T_ref: the dwells' weighted mean temperature (the calibration's)
  double spread_c = 0;     // weighted SD of the dwells' temperatures about it
  size_t dwells = 0;       // dwells with a temperature
  Eigen::Matrix<double, 8, 1> shift_scaled = Eigen::Matrix<double, 8, 1>::Zero();  // per arcsec/C
  double sensitivity_arcsec_per_c = 0;  // kappa: d(sensor angle - reference) / dT
  double sensitivity_sigma = 0;         // its 1-sigma (NaN: the temperatures did not vary)
  double dof = 0;
  // The angle's standard uncertainty per arcsec of shift (angle_shift_arcsec of shift_scaled): kappa
  // is not corrected for, so its estimate counts with its sigma (GUM F.2.4.5: an uncorrected effect
  // enlarges the uncertainty).
  double u_per_shift() const {
    return std::hypot(sensitivity_arcsec_per_c, std::isfinite(sensitivity_sigma) ? sensitivity_sigma : 0.0);
  }
};

struct Uncertainty {
  std::array<double, 8> sigma{};  // 1-sigma of C1..C8, in the coefficients' units
  Eigen::Matrix<double, 8, 8> covariance = Eigen::Matrix<double, 8, 8>::Zero();  // of C1..C8
  double residual_sigma_arcsec = 0;  // scale of the covariance: sqrt(sum r^2 / (m - p))
  // max over the count range of sqrt(J cov J^T), with the temperature's entry (known) beside it
  double angle_sigma_max_arcsec = 0;
  double angle_sigma_at_counts = 0;  // where that max is
  bool pseudo_inverse = false;  // J^T J was rank deficient: Moore-Penrose pseudo-inverse
  std::string note;
  // Of the scaled coefficients u[0..7] (u[0] = C1 in arcsec, residuals.h), what the angle sigma
  // at any count is computed from (angle_sigma_arcsec).
  Eigen::Matrix<double, 8, 8> covariance_scaled = Eigen::Matrix<double, 8, 8>::Zero();
  // The noise model's share of covariance_scaled by its source (NoiseSource), before any
  // sigma_scale: they sum to covariance_scaled / sigma_scale^2. Known only for the GLS with a
  // noise model (sources_known); the uncertainty budget (calibration.json) is built from them.
  std::array<Eigen::Matrix<double, 8, 8>, 3> source_covariance_scaled{};
  bool sources_known = false;
  TemperatureInfluence temperature;  // (GlsData::temperature_c)
};

// The sources a dwell mean's variance is made of, in the order of source_covariance_scaled.
enum class NoiseSource { sensor, quantisation, reference };

// 1-sigma of the fitted angle at `counts`, arcsec, from one scaled covariance.
double angle_sigma_arcsec(const Eigen::Matrix<double, 8, 8>& covariance_scaled, const AxisCoeffs& fit, double counts);

// d angle(counts) / d(u[1..7], level), arcsec per scaled unit: one dwell's row of the GLS's
// Jacobian (DwellLevelResidual, the fit's own functor, with C1 as the level). The design predicts
// the fit's Fisher information from it.
Eigen::Matrix<double, 8, 1> dwell_gradient(const AxisCoeffs& c, double counts);

// 1-sigma of the fitted angle at `counts`, arcsec, from the scaled covariance (C1 included).
double angle_sigma_arcsec(const Uncertainty& u, const AxisCoeffs& fit, double counts);

// The fitted angle's change at `counts`, arcsec, when the scaled coefficients move by `shift`.
double angle_shift_arcsec(const Eigen::Matrix<double, 8, 1>& shift_scaled, const AxisCoeffs& fit, double counts);

// The dwells as the fit with the changes' covariance sees them: every change null <-> offset is
// the difference of two dwells, so fitting the changes with their covariance (GLS) is fitting the
// dwells with one free reference level per set of dwells the changes join (the changes lose
// exactly that level), each dwell weighted by its own variance. Prepared by the calibrator.
struct GlsData {
  const std::deque<AxisData::DwellRow>* dwells = nullptr;  // the dwells: reference angle, frames
  std::vector<double> counts;           // the dwell's count (quantisation-corrected when known)
  std::vector<float> var_counts2;       // variance of the count estimate, counts^2
  // The sensor noise's part of var_counts2 (what is left is quantisation's); empty: all of it.
  std::vector<float> var_sensor_counts2;
  std::vector<uint32_t> level;          // which reference level, 0 .. levels - 1 (empty: all in level 0)
  std::vector<double> level_share;      // C1 = sum share_g level_g: the null condition over null dwells
  size_t levels = 0;
  double ref_var_arcsec2 = 0;           // reference variance per frame (pooled within-dwell scatter)
  // Variances from a noise model (given or from within-dwell scatter); false: equal weights, and
  // the covariance is scaled by the residuals.
  bool noise_known = true;
  // The dwells' sensor temperatures, C (NaN: none); null or all NaN: the recording has none.
  const std::deque<float>* temperature_c = nullptr;
  size_t size() const { return counts.size(); }
  double ref_arcsec(size_t k) const { return (*dwells)[k].ref_arcsec; }
  uint32_t level_of(size_t k) const { return level.empty() ? 0u : level[k]; }
  // Variance of the dwell's reference mean.
  float var_ref_arcsec2(size_t k) const {
    return static_cast<float>(ref_var_arcsec2 / std::max(1.0, (*dwells)[k].ref_readings()));
  }
};

struct GlsFit {
  AxisCoeffs coeffs{};  // C1 from the levels (the null condition)
  int iterations = 0;
  bool converged = false;
  double chi2 = 0;  // sum of squared standardised residuals
  size_t dof = 0;
  double reduced_chi2 = 0;
  // chi2 / dof materially above 1 (more than `remainder_sigmas` of its own scatter, sqrt(2 / dof)):
  // the model does not describe the data; the covariance is then scaled by reduced_chi2.
  bool model_remainder = false;
  double sigma_scale = 1;  // factor applied to every sigma (1, or sqrt(reduced_chi2))
  Uncertainty uncertainty;
};

// Ceres's Levenberg-Marquardt from `start` (the changes' least-squares fit) over C2..C8 and one
// level per joined set of dwells, the sinusoids as a sin + b cos while iterating; runs of dwells
// are residual blocks compressed by QR (TSQR), so memory does not grow with the dwells. The
// covariance is the levels-projected Fisher information at the solution.
GlsFit refine_gls(const GlsData& g, const AxisCoeffs& start, double counts_lo, double counts_hi,
                  double remainder_sigmas = 3.0);

// Least squares from `start` over an evenly spread `fraction` of the rows of `d` (in_spread_subset).
// Throws nothing on a poor fit; `usable` false means Ceres could not produce a solution.
Refined refine_axis(const AxisData& d, const AxisCoeffs& start, const RefineOptions& opts, double fraction = 1.0);

// A Gaussian prior on the scaled coefficients (residuals.h): weight[i] (1 / sigma_i^2, in the units
// of the rows' squared residuals) about u0; a weight of 0 leaves that coefficient free.
struct ScaledPrior {
  Scaled u0{};
  std::array<double, 8> weight{};
};

// Least squares of eq. 1, C1..C8, on absolute rows (counts, angle in arcsec) from `start`, with an
// optional prior: the diagnosis's refit of a sensor's transfer function. The same solver and
// functor as refine_axis; the coefficients are returned as fitted (not normalised), so a prior's
// phases keep their meaning across calls.
Refined refine_rows(const std::vector<double>& counts, const std::vector<double>& angle_arcsec, const AxisCoeffs& start,
                    const RefineOptions& opts, const ScaledPrior* prior = nullptr);

// The covariance of the coefficients at `fit` over all rows, scaled by the residual variance.
// The differences method's C1 inherits its uncertainty through the null condition; the angle
// uncertainty then is that of the angle relative to null (zero at the null counts).
Uncertainty uncertainty(const AxisData& d, const AxisCoeffs& fit, const RefineOptions& opts);

// The same function with positive frequencies and phases in (-pi, pi]: sin(-wN + p) = -sin(wN - p).
void normalise(AxisCoeffs& c);

// C1 of the differences method: angle(mean null counts) = mean null reference (eq. 3; the
// bench reference reads zero at null, so this is the paper's angle(N_null) = 0).
double null_condition_c1(const AxisData& d, const AxisCoeffs& c);

}  // namespace fpss::fit
