// The engine's own helpers, shared by its parts (the run, the measurer, the scheduler, the clock); not an interface.
#pragma once
#include <fmt/format.h>

#include <chrono>
#include <stdexcept>
#include <string>

#include "drivers/gimbal.h"
#include "procedures/events.h"
#include "procedures/plan.h"

namespace fpss {

namespace engine_detail {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Adds the time spent in a scope to a counter.
struct Timed {
  explicit Timed(double& acc) : acc_(acc), t0_(Clock::now()) {}
  ~Timed() { acc_ += seconds_since(t0_); }
  double& acc_;
  Clock::time_point t0_;
};

inline std::string fault_name(const GimbalState& st) {
  return st.fault != GimbalFault::none ? to_string(st.fault) : "fault bit set";
}

inline std::string deg(double arcsec) { return fmt::format("{:+.4f} deg", arcsec / 3600.0); }

inline std::string label(const Action& a) {
  return a.is_point() ? fmt::format("point {}", a.point + 1) : fmt::format("step {}", a.step_index);
}

// Failures of one measurement attempt, by the device that caused them, so recovery knows what to
// reset, each with the stop cause it becomes when no attempt succeeds.
struct SensorFailure : std::runtime_error {
  explicit SensorFailure(const std::string& what, StopCause c = StopCause::sensor_timeout)
      : std::runtime_error(what), cause(c) {}
  StopCause cause;
};
// The recording could not be made durable: never re-measured, the run stops.
struct StorageFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};
struct GimbalFailure : std::runtime_error {
  explicit GimbalFailure(const std::string& what, StopCause c = StopCause::gimbal_fault, bool is_final = false)
      : std::runtime_error(what), cause(c), final(is_final) {}
  StopCause cause;
  bool final;  // no attempt more: the run stops (another client moving the gimbal)
};
// A failure no other device can explain (a step's check, a fit, a move that cannot be put back).
struct PointFailure : std::runtime_error {
  explicit PointFailure(const std::string& what, StopCause c = StopCause::other)
      : std::runtime_error(what), cause(c) {}
  StopCause cause;
  bool sensor_side = false;  // the last attempt failed on the sensor's side (several units: the lead may be dropped)
};
// The operator or a signal asked for the abort: unwinds to run(), which stops safely.
struct Aborted {};

}  // namespace engine_detail

}  // namespace fpss
