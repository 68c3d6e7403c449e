#include "stand/session/computation_checks.h"

#include <fmt/format.h>

namespace fpss {

std::string check_limits(const ResidualLimits& lim, const ResidualStats& r, const char* axis) {
  std::string broken;
  auto add = [&](std::string s) { broken += (broken.empty() ? "" : "; ") + s; };
  if (lim.mean_abs_arcsec && r.mean_abs_arcsec > *lim.mean_abs_arcsec) {
    add(fmt::format("{} mean |residual| {:.3f} arcsec > {} arcsec", axis, r.mean_abs_arcsec, *lim.mean_abs_arcsec));
  }
  if (lim.sd_arcsec && r.sd_arcsec > *lim.sd_arcsec) {
    add(fmt::format("{} residual sd {:.3f} arcsec > {} arcsec", axis, r.sd_arcsec, *lim.sd_arcsec));
  }
  if (lim.max_abs_arcsec && r.max_abs_arcsec > *lim.max_abs_arcsec) {
    add(fmt::format("{} max |residual| {:.3f} arcsec > {} arcsec", axis, r.max_abs_arcsec, *lim.max_abs_arcsec));
  }
  if (lim.min_points && static_cast<int64_t>(r.points) < *lim.min_points) {
    add(fmt::format("{} {} points < {}", axis, r.points, *lim.min_points));
  }
  return broken;
}

// Residuals a hundred times the limit are not a worn sensor: the recording and the model disagree
// about which way the axes point, or the model is not this sensor's.
bool absurd(const ResidualLimits& lim, const ResidualStats& r) {
  auto over = [](const std::optional<double>& limit, double value) { return limit && value > 100 * *limit; };
  return over(lim.mean_abs_arcsec, r.mean_abs_arcsec) || over(lim.sd_arcsec, r.sd_arcsec) ||
         over(lim.max_abs_arcsec, r.max_abs_arcsec);
}

std::string check_calibration(const CheckStep& step, const CalibrationReport& cal) {
  std::string broken = check_limits(step.pitch, cal.pitch.residuals, "pitch");
  const std::string y = check_limits(step.yaw, cal.yaw.residuals, "yaw");
  if (!y.empty()) broken += (broken.empty() ? "" : "; ") + y;
  if (absurd(step.pitch, cal.pitch.residuals) || absurd(step.yaw, cal.yaw.residuals)) {
    broken += ". Residuals over 100x the limit: the likely cause is the stand file's axis mapping (axes:, which "
              "must match how the sensor is mounted) or the coefficients (the calibrate step's init); see "
              "docs/procedures.md, \"Axis mapping\"";
  }
  return broken;
}

}  // namespace fpss
