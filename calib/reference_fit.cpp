#include "calib/reference_fit.h"

#include <algorithm>
#include <cmath>

#include "calib/units.h"

namespace fpss {

namespace {

double extent_arcsec(const AxisFit& a) {
  return kArcsecPerDeg * std::max(std::abs(a.residuals.range_deg[0]), std::abs(a.residuals.range_deg[1]));
}

void grow(AxisFit& a, const CalibrationOptions& opts, int sensor_axis, double other_extent_arcsec) {
  const ReferenceCalibration& ref = *opts.reference;
  double worst = 0;
  for (size_t i = 0; i < a.angle_sigma_arcsec.size(); ++i) {
    auto& [angle, sigma] = a.angle_sigma_arcsec[i];
    const std::vector<BudgetEntry> terms = reference_budget(ref, opts.mount, sensor_axis, angle, other_extent_arcsec);
    const double u = root_sum_square(terms);
    sigma = std::hypot(sigma, u);  // infinite stays infinite: the fit cannot speak there either
    worst = std::max(worst, u);
    if (i < a.angle_budget.size() && !a.angle_budget[i].empty()) {
      a.angle_budget[i].insert(a.angle_budget[i].end(), terms.begin(), terms.end());
    }
  }
  if (a.angle_sigma_arcsec.empty()) {
    // No list: the worst over the calibrated range's ends.
    const double e = extent_arcsec(a);
    worst = std::max(reference_u_arcsec(ref, opts.mount, sensor_axis, -e, other_extent_arcsec),
                     reference_u_arcsec(ref, opts.mount, sensor_axis, e, other_extent_arcsec));
  }
  a.reference_u_max_arcsec = worst;
  a.angle_sigma_max_arcsec = std::hypot(a.angle_sigma_max_arcsec, worst);
}

}  // namespace

double other_axis_extent_arcsec(const CalibrationReport& rep, int sensor_axis) {
  return extent_arcsec(sensor_axis == 0 ? rep.yaw : rep.pitch);
}

void add_reference_uncertainty(CalibrationReport& rep, const CalibrationOptions& opts) {
  if (!opts.reference) return;
  grow(rep.pitch, opts, 0, other_axis_extent_arcsec(rep, 0));
  grow(rep.yaw, opts, 1, other_axis_extent_arcsec(rep, 1));
  nlohmann::json block = opts.reference->identity();
  block["corrected_by"] = opts.correct_reference ? "calibrate" : "run";
  rep.reference = block;
}

SampleTable with_reference_applied(const SampleTable& t, const CalibrationOptions& opts) {
  SampleTable out = t;
  if (!opts.reference || !opts.correct_reference) return out;
  for (size_t i = 0; i < out.size(); ++i) {
    correct_reference_angles(*opts.reference, opts.mount, out.ref_pitch_arcsec[i], out.ref_yaw_arcsec[i]);
  }
  return out;
}

}  // namespace fpss
