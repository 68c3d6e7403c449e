// Aligning two device clocks: sensor frames get the gimbal's position interpolated to their own time.
#pragma once
#include <cstdint>
#include <optional>
#include <vector>

namespace fpss {

// One gimbal reading on the gimbal's clock.
struct GimbalFix {
  double gimbal_time_s = 0;
  double host_time_s = 0;  // host steady clock at receipt
  double pitch_arcsec = 0, yaw_arcsec = 0;
  double pitch_rate_arcsec_s = 0, yaw_rate_arcsec_s = 0;
  uint16_t status = 0;
};

// The gimbal position at gimbal time t from the two readings around it: cubic Hermite on their
// positions and rates (exact for constant acceleration, so a reading missed while the axis
// accelerates costs little); nullopt outside the readings (no extrapolation). `fixes` sorted by
// gimbal_time_s.
struct Interpolated {
  double pitch_arcsec = 0, yaw_arcsec = 0;
  uint16_t status = 0;  // of the reading before t
  double gap_s = 0;     // time between the two readings used
};
std::optional<Interpolated> interpolate_at(const std::vector<GimbalFix>& fixes, double t_s);

// Device clock -> host clock offset from the lower envelope of (scale * host - device): the
// frames with the least transport latency bound it. scale is bench seconds per host second.
// Returns c such that device_time + c ~= scale * host_time at emission.
double clock_offset(const std::vector<double>& host_s, const std::vector<double>& device_s, double scale);

// A 32-bit microsecond counter (the sensor's) unwrapped to the nearest value of a 64-bit
// reference on the same clock (the gimbal's, on a shared-clock bench).
double unwrap_near(uint32_t counter_us, double reference_s);

}  // namespace fpss
