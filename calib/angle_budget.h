// The calibration's uncertainty budget per listed angle: the fit's covariance by source, the temperature's entry, the angles' sigmas.
#pragma once
#include <array>
#include <optional>
#include <vector>

#include "calib/calibrator.h"
#include "calib/refine.h"
#include "calib/uncertainty.h"

namespace fpss::fit {

// The fit's covariance split by source: the noise model's sources, and the model-and-fit
// remainder (what sigma_scale adds to them); without a noise model the whole covariance is the
// residuals' scatter (model and fit).
std::vector<AxisFit::CovarianceSource> covariance_sources(const AxisFit& out, const Uncertainty& u, const AxisData& d);

// `count` evenly spaced angles over the calibrated range (or `range_arcsec`), each with its sigma
// and its budget (AxisFit::angle_sigma_arcsec, angle_budget).
void list_angle_sigmas(AxisFit& out, const Uncertainty& u, const AxisData& d, int count,
                       const std::optional<std::array<double, 2>>& range_arcsec);

}  // namespace fpss::fit
