#include "procedures/align.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fpss {

std::optional<Interpolated> interpolate_at(const std::vector<GimbalFix>& fixes, double t_s) {
  if (fixes.empty() || t_s < fixes.front().gimbal_time_s || t_s > fixes.back().gimbal_time_s) return std::nullopt;
  auto hi = std::lower_bound(fixes.begin(), fixes.end(), t_s,
                             [](const GimbalFix& f, double t) { return f.gimbal_time_s < t; });
  if (hi == fixes.begin()) return Interpolated{hi->pitch_arcsec, hi->yaw_arcsec, hi->status, 0.0};
  auto lo = hi - 1;
  const double h = hi->gimbal_time_s - lo->gimbal_time_s;
  if (h <= 0) return Interpolated{hi->pitch_arcsec, hi->yaw_arcsec, lo->status, 0.0};
  const double u = (t_s - lo->gimbal_time_s) / h;
  const double h00 = (1 + 2 * u) * (1 - u) * (1 - u), h10 = u * (1 - u) * (1 - u);
  const double h01 = u * u * (3 - 2 * u), h11 = u * u * (u - 1);
  auto herm = [&](double p0, double v0, double p1, double v1) { return h00 * p0 + h10 * h * v0 + h01 * p1 + h11 * h * v1; };
  return Interpolated{herm(lo->pitch_arcsec, lo->pitch_rate_arcsec_s, hi->pitch_arcsec, hi->pitch_rate_arcsec_s),
                      herm(lo->yaw_arcsec, lo->yaw_rate_arcsec_s, hi->yaw_arcsec, hi->yaw_rate_arcsec_s), lo->status, h};
}

double clock_offset(const std::vector<double>& host_s, const std::vector<double>& device_s, double scale) {
  double best = std::numeric_limits<double>::infinity();
  const size_t n = std::min(host_s.size(), device_s.size());
  for (size_t i = 0; i < n; ++i) best = std::min(best, scale * host_s[i] - device_s[i]);
  return n ? best : 0.0;
}

double unwrap_near(uint32_t counter_us, double reference_s) {
  constexpr double kWrapS = 4294967296.0 * 1e-6;
  const double base = static_cast<double>(counter_us) * 1e-6;
  const double k = std::round((reference_s - base) / kWrapS);
  return base + k * kWrapS;
}

}  // namespace fpss
