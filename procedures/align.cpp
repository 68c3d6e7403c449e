#include "procedures/align.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fpss {

std::optional<Interpolated> interpolate_at(const std::vector<GimbalFix>& fixes, double t_s) {
  if (fixes.empty() || t_s < fixes.front().gimbal_time_s || t_s > fixes.back().gimbal_time_s) return std::nullopt;
  auto hi = std::lower_bound(fixes.begin(), fixes.end(), t_s,
                             [](const GimbalFix& f, double t) { return f.gimbal_time_s < t; });
  if (hi == fixes.begin()) return Interpolated{hi->pitch_arcsec, hi->yaw_arcsec, hi->status};
  auto lo = hi - 1;
  const double span = hi->gimbal_time_s - lo->gimbal_time_s;
  const double w = span > 0 ? (t_s - lo->gimbal_time_s) / span : 0.0;
  return Interpolated{lo->pitch_arcsec + w * (hi->pitch_arcsec - lo->pitch_arcsec),
                      lo->yaw_arcsec + w * (hi->yaw_arcsec - lo->yaw_arcsec), lo->status};
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
