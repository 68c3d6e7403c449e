#include "procedures/check_report.h"

#include <fmt/format.h>

#include "calib/calibrator.h"

namespace fpss {

namespace {

void join(std::string& to, const std::string& clause, const char* sep = "; ") {
  if (!to.empty()) to += sep;
  to += clause;
}

void check_axis(const ResidualLimits& lim, const ResidualStats& r, const char* axis, std::vector<LimitBreach>& out) {
  using Q = LimitBreach::Quantity;
  if (lim.mean_abs_arcsec && r.mean_abs_arcsec > *lim.mean_abs_arcsec) {
    out.push_back({axis, Q::mean_abs, r.mean_abs_arcsec, *lim.mean_abs_arcsec});
  }
  if (lim.sd_arcsec && r.sd_arcsec > *lim.sd_arcsec) out.push_back({axis, Q::sd, r.sd_arcsec, *lim.sd_arcsec});
  if (lim.max_abs_arcsec && r.max_abs_arcsec > *lim.max_abs_arcsec) {
    out.push_back({axis, Q::max_abs, r.max_abs_arcsec, *lim.max_abs_arcsec});
  }
  if (lim.min_points && static_cast<int64_t>(r.points) < *lim.min_points) {
    out.push_back({axis, Q::points, static_cast<double>(r.points), static_cast<double>(*lim.min_points)});
  }
}

// Residuals a hundred times the limit are not a worn sensor: the recording and the model disagree
// about which way the axes point, or the model is not this sensor's.
bool absurd(const ResidualLimits& lim, const ResidualStats& r) {
  auto over = [](const std::optional<double>& limit, double value) { return limit && value > 100 * *limit; };
  return over(lim.mean_abs_arcsec, r.mean_abs_arcsec) || over(lim.sd_arcsec, r.sd_arcsec) ||
         over(lim.max_abs_arcsec, r.max_abs_arcsec);
}

}  // namespace

std::string LimitBreach::text() const {
  switch (quantity) {
    case Quantity::mean_abs: return fmt::format("{} mean |residual| {:.3f} arcsec > {} arcsec", axis, value, limit);
    case Quantity::sd: return fmt::format("{} residual sd {:.3f} arcsec > {} arcsec", axis, value, limit);
    case Quantity::max_abs: return fmt::format("{} max |residual| {:.3f} arcsec > {} arcsec", axis, value, limit);
    case Quantity::points:
      return fmt::format("{} {} points < {}", axis, static_cast<int64_t>(value), static_cast<int64_t>(limit));
  }
  return {};
}

std::string UnitCheck::text() const {
  if (!calibrated) return "no calibration to check";
  std::string s;
  for (const auto& b : breaches) join(s, b.text());
  if (absurd) {
    s += ". Residuals over 100x the limit: the likely cause is the stand file's axis mapping (axes:, which "
         "must match how the sensor is mounted) or the coefficients (the calibrate step's init); see "
         "docs/procedures.md, \"Axis mapping\"";
  }
  return s;
}

bool CheckReport::passed() const {
  for (const auto& u : units) {
    if (!u.passed()) return false;
  }
  return true;
}

std::string CheckReport::summary() const {
  std::string s;
  for (const auto& u : units) {
    if (!u.calibrated) return u.text();
    if (u.passed()) continue;
    join(s, (u.unit.empty() ? "" : "unit " + u.unit + " ") + u.text());
  }
  return s;
}

UnitCheck check_calibration(const CheckStep& step, const ResidualStats& pitch, const ResidualStats& yaw,
                            std::string unit) {
  UnitCheck c;
  c.unit = std::move(unit);
  check_axis(step.pitch, pitch, "pitch", c.breaches);
  check_axis(step.yaw, yaw, "yaw", c.breaches);
  c.absurd = absurd(step.pitch, pitch) || absurd(step.yaw, yaw);
  return c;
}

}  // namespace fpss
