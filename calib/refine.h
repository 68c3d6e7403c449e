// The nonlinear refinement of one axis with Ceres, and its covariance. The only place that
// includes ceres.h (refine.cpp), to keep the build cheap.
#pragma once
#include <array>
#include <cstddef>
#include <string>

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

struct Uncertainty {
  std::array<double, 8> sigma{};  // 1-sigma of C1..C8, in the coefficients' units
  Eigen::Matrix<double, 8, 8> covariance = Eigen::Matrix<double, 8, 8>::Zero();  // of C1..C8
  double residual_sigma_arcsec = 0;  // scale of the covariance: sqrt(sum r^2 / (m - p))
  double angle_sigma_max_arcsec = 0;  // max over the count range of sqrt(J cov J^T)
  double angle_sigma_at_counts = 0;  // where that max is
  bool pseudo_inverse = false;  // J^T J was rank deficient: Moore-Penrose pseudo-inverse
  std::string note;
};

// Least squares from `start` over an evenly spread `fraction` of the rows of `d` (in_spread_subset).
// Throws nothing on a poor fit; `usable` false means Ceres could not produce a solution.
Refined refine_axis(const AxisData& d, const AxisCoeffs& start, const RefineOptions& opts, double fraction = 1.0);

// The covariance of the coefficients at `fit` over all rows, scaled by the residual variance.
// The differences method's C1 inherits its uncertainty through the null condition; the angle
// uncertainty then is that of the angle relative to null (zero at the null counts).
Uncertainty uncertainty(const AxisData& d, const AxisCoeffs& fit, const RefineOptions& opts);

// C1 of the differences method: angle(mean null counts) = mean null reference (eq. 3; the
// bench reference reads zero at null, so this is the paper's angle(N_null) = 0).
double null_condition_c1(const AxisData& d, const AxisCoeffs& c);

}  // namespace fpss::fit
