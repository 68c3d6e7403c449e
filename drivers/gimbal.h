// The two-axis sun-simulator gimbal as the stand sees it: an interface; ModbusGimbal is the real driver.
#pragma once
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

#include "drivers/device.h"

namespace fpss {

// Status register bits (ICD, input register 8).
enum GimbalStatusBit : uint16_t {
  kHomed = 1u << 0, kMoving = 1u << 1, kInPosition = 1u << 2, kFault = 1u << 3,
  kPitchLimit = 1u << 4, kYawLimit = 1u << 5, kRateMode = 1u << 6, kMovePending = 1u << 7,
};

// Fault codes (ICD, input register 9).
enum class GimbalFault : uint16_t {
  none = 0, following_error = 1, limit = 2, estop = 3, watchdog = 4, bad_command = 5,
};
const char* to_string(GimbalFault f);

struct GimbalState {
  double pitch_arcsec = 0, yaw_arcsec = 0;  // encoder positions
  double pitch_rate_arcsec_s = 0, yaw_rate_arcsec_s = 0;
  uint16_t status = 0;  // GimbalStatusBit
  GimbalFault fault = GimbalFault::none;
  uint64_t sample_time_us = 0;  // the gimbal's clock (bench clock when emulated)
  uint16_t moves_completed = 0;
  double host_time_s = 0;  // host steady clock at receipt

  bool has(GimbalStatusBit b) const { return (status & b) != 0; }
};

// Soft limits of the stand, enforced by the driver before anything is sent.
struct SoftLimits {
  double pitch_min_arcsec = -2700, pitch_max_arcsec = 2700;
  double yaw_min_arcsec = -2700, yaw_max_arcsec = 2700;
  double max_rate_arcsec_s = 3600;
};

// A device failure after retries (timeout, exception, disconnect): what, where and errno.
struct DeviceError : std::runtime_error {
  using std::runtime_error::runtime_error;
};
// A request the driver refuses before touching the wire (soft limit, bad argument).
struct LimitError : DeviceError {
  using DeviceError::DeviceError;
};

// What the gimbal was last commanded (its holding registers), whoever commanded it.
struct GimbalCommand {
  double target_pitch_arcsec = 0, target_yaw_arcsec = 0;
  double max_rate_arcsec_s = 0;
  double watchdog_s = 0;
  uint16_t command = 0;  // the command register's last value (1 move, 2 stop, 3 home, 4 clear fault, 5 rate, 6 move at)
};

class Gimbal : public Device {
 public:
  virtual GimbalState read_state() = 0;
  virtual void set_max_rate(double arcsec_s) = 0;
  // Absolute move; throws LimitError outside the soft limits, nothing sent.
  virtual void move_to(double pitch_arcsec, double yaw_arcsec) = 0;
  // Whether the gimbal can start a move at a set time of its own clock (known once connected).
  virtual bool timed_moves() const { return false; }
  // The move to the target starts when the gimbal's clock reaches start_us
  // (GimbalState::sample_time_us), from rest or queued behind the move under way, but not before
  // that move has arrived and a reading has found the gimbal at rest there (then at that reading's
  // time stamp); until it starts its status has kMovePending. One waits at most: a new one
  // replaces it. A time already past is refused (DeviceError; a move already pending stays). Any
  // other command cancels it. Only where timed_moves() (docs/icd.md).
  virtual void move_at(double pitch_arcsec, double yaw_arcsec, uint64_t start_us) {
    (void)pitch_arcsec, (void)yaw_arcsec, (void)start_us;
    throw DeviceError("this gimbal cannot start a move at a set time");
  }
  // Polls until in position and not moving; throws DeviceError on fault or timeout (wall seconds).
  virtual GimbalState wait_in_position(double timeout_s) = 0;
  virtual void start_rate(double pitch_arcsec_s, double yaw_arcsec_s) = 0;
  virtual void stop() = 0;
  virtual void home() = 0;
  virtual void clear_fault() = 0;
  virtual void set_watchdog(double seconds) = 0;  // 0 turns it off
  // Reads back what the gimbal was commanded, so a controller notices another client's writes;
  // nullopt from a gimbal that cannot say.
  virtual std::optional<GimbalCommand> read_command() { return std::nullopt; }
};

}  // namespace fpss
