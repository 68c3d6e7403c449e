#include "procedures/settings.h"

#include <fmt/format.h>

namespace fpss {

nlohmann::json to_json(const EngineSettings& b) {
  auto axis = [](double sign, AxisMapping::SensorAxis a) {
    return fmt::format("{}{}", sign < 0 ? "-" : "", a == AxisMapping::alpha ? "alpha" : "beta");
  };
  return {
      {"soft_limits",
       {{"pitch_arcsec", {b.limits.pitch_min_arcsec, b.limits.pitch_max_arcsec}},
        {"yaw_arcsec", {b.limits.yaw_min_arcsec, b.limits.yaw_max_arcsec}},
        {"max_rate_arcsec_s", b.limits.max_rate_arcsec_s}}},
      {"axes", {{"pitch", axis(b.axes.pitch_sign, b.axes.pitch_axis)}, {"yaw", axis(b.axes.yaw_sign, b.axes.yaw_axis)}}},
      {"profile_rate_arcsec_s", b.profile_rate_arcsec_s}, {"acceleration_arcsec_s2", b.acceleration_arcsec_s2},
      {"in_position_tolerance_arcsec", b.in_position_tolerance_arcsec},
      {"move_timeout_s", b.move_timeout_s}, {"home_timeout_s", b.home_timeout_s},
      {"frame_timeout_s", b.frame_timeout_s},
      {"sample_rate_hz", b.sample_rate_hz}, {"max_remeasure", b.max_remeasure}, {"watchdog_s", b.watchdog_s},
      {"clock", b.clock == ClockSync::shared ? "shared" : "host"}, {"sensor_time_offset_s", b.sensor_time_offset_s},
      {"max_reference_gap_s", b.max_reference_gap_s}, {"time_scale", b.time_scale},
      {"link_round_trip_s", b.link_round_trip_s}, {"timed_moves", b.timed_moves},
  };
}

}  // namespace fpss
