// The engine's estimate of time: the bench's clock from the devices' stamps, stand time from the sensor's, the frame grid.
#pragma once
#include <cmath>
#include <limits>
#include <optional>

#include "drivers/sensor.h"
#include "procedures/plan.h"
#include "procedures/recorder.h"
#include "procedures/settings.h"

namespace fpss {

// Host clocks (the devices keep their own): when a frame was taken, on the host's steady clock. The
// sensor stamps each frame on its own clock, which runs at the bench's pace, and the link only ever
// delays a frame: the smallest receipt-minus-stamp seen is the link's own delay, so a frame stamped
// s was taken at s plus that. A stalled stream catching up in a burst then shows its frames as
// taken when they were, not when they came. The smallest delay may rise by 100 ppm of the time
// since (the two clocks' drift), and starts again when the sensor's clock restarts. One per sensor.
class FrameTakenClock {
 public:
  explicit FrameTakenClock(double time_scale) : time_scale_(time_scale) {}
  void note(const SensorSample& f);
  double taken_host_s(const SensorSample& f) const;

 private:
  double time_scale_;
  std::optional<double> link_delay_s_;  // host receipt - sensor stamp (host seconds), the smallest seen
  double last_sensor_s_ = 0, last_host_s_ = 0;  // the last noted frame's stamp and receipt
};

// The devices stamp their readings on their own clocks and the host only receives them: everything
// the engine waits for is in bench time, which the host can only estimate between two stamps.
class EngineClock {
 public:
  explicit EngineClock(const EngineSettings& bench)
      : b_(bench), sensor_offset_s_(bench.sensor_time_offset_s), lead_taken_(bench.time_scale) {}

  // A session's start: stand time goes on from a resumed run's last time, and from the time the
  // run was down (at the bench's pace).
  void start(const ResumePoint& from);
  // The drivers stamp receipts with the same steady clock (SensorSample/GimbalState::host_time_s).
  double host_now_s() const;
  double session_host_s(double host_s) const { return host_s - host_t0_; }

  void note_bench(double bench_s, double host_s);
  // A gimbal reading's stamp: it is also what a shared clock's sensor time is unwrapped against.
  void note_gimbal(double gimbal_s, double host_s);
  // The bench clock (the devices' own) now: the latest device time stamp, advanced by the host
  // clock since at the bench's pace.
  double bench_now_s() const { return bench_now_at(host_now_s()); }
  double bench_now_at(double host_s) const;
  double last_bench_s() const { return last_bench_s_; }
  double last_gimbal_s() const { return last_gimbal_time_s_; }

  // Stand time: base + (sensor time - sensor t0), kept non-decreasing across sensor restarts.
  double stand_time(double sensor_time_s);
  // The same mapping without moving it on: for another unit's frames on the same clock.
  double stand_time_of(double sensor_time_s) const {
    const double t = sensor_t0_ ? time_base_ + (sensor_time_s - *sensor_t0_) : last_time_;
    return std::round(t * 1e6) / 1e6;
  }
  // A frame's time on the device clock: the lead's offset (set_sensor_offset_s), or another unit's.
  double sensor_clock_s(const SensorSample& f) const { return sensor_clock_s(f, sensor_offset_s_); }
  double sensor_clock_s(const SensorSample& f, double offset_s) const;
  void set_sensor_offset_s(double s) { sensor_offset_s_ = s; }
  double sensor_offset_s() const { return sensor_offset_s_; }

  // A frame's time (shared clock): the sensor's frames come on a grid of its period from it.
  bool frame_grid_known() const { return std::isfinite(frame_grid_s_); }
  void note_frame(double sensor_clock_s) { frame_grid_s_ = sensor_clock_s; }
  // The first frame at or after t_s on the sensor's frame grid (one clock for both devices).
  double first_frame_from(double t_s) const;
  // When a dwell of `a` whose first frame is at first_frame_s ends: half a frame period after its
  // last frame, when the move after it is scheduled to start.
  double dwell_end_s(const Action& a, double first_frame_s) const;

  // Host clocks: when one of the lead's frames was taken (FrameTakenClock).
  void note_sensor_frame(const SensorSample& f) { lead_taken_.note(f); }
  double taken_host_s(const SensorSample& f) const { return lead_taken_.taken_host_s(f); }

  // Bench time counts from the next gimbal reading: the link's setup before it is not the procedure's.
  void count_bench_from_next_reading() { bench_start_s_ = -1; }
  void reset_bench_count() {
    bench_start_s_ = -1;
    off_bench_s_ = 0;
  }
  void add_off_bench(double s) { off_bench_s_ += s; }
  // Bench seconds counted since the first reading, computation steps left out; nullopt if none came.
  std::optional<double> bench_s() const;

 private:
  const EngineSettings& b_;
  double sensor_offset_s_;  // the lead's clock offset (stand file clock.sensor_offset_s, or its own)
  double host_t0_ = 0;
  std::optional<double> sensor_t0_;
  double time_base_ = 0, last_time_ = 0;
  double last_gimbal_time_s_ = 0;
  double frame_grid_s_ = std::numeric_limits<double>::quiet_NaN();
  double last_bench_s_ = 0, last_bench_host_s_ = 0;  // the latest device time stamp and its receipt
  FrameTakenClock lead_taken_;
  double bench_start_s_ = -1, off_bench_s_ = 0;
};

}  // namespace fpss
