// What the engine needs to know about a stand: limits, axis mapping, timing and recovery policy.
#pragma once
#include <optional>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "calib/axis_mapping.h"
#include "calib/reference_calibration.h"
#include "drivers/gimbal.h"

namespace fpss {

// How sensor time and gimbal time relate. `host`: separate clocks, related through the host's
// receive times (lower envelope of the latency). `shared`: both report one clock (a bench with a
// common timebase, or the emulator's bench clock).
enum class ClockSync { host, shared };

struct EngineSettings {
  SoftLimits limits;
  AxisMapping axes;
  double profile_rate_arcsec_s = 1800;   // gimbal profile speed for moves
  double acceleration_arcsec_s2 = 3600;  // for duration estimates and to predict a move's arrival
  double in_position_tolerance_arcsec = 1.0;  // the engine's own arrival check on the encoders
  double move_timeout_s = 30;            // physical seconds for one move
  double home_timeout_s = 60;
  double frame_timeout_s = 1.0;          // wall seconds a frame may be late beyond its period
  double sample_rate_hz = 50;            // sensor stream rate (RATE)
  int max_remeasure = 3;                 // re-measurements of one point before a safe stop
  double watchdog_s = 0;                 // gimbal watchdog during the run (0: off)
  ClockSync clock = ClockSync::host;
  double sensor_time_offset_s = 0;       // added to sensor time before aligning (known latency)
  double max_reference_gap_s = 0.05;     // slews: a frame between gimbal readings further apart is skipped
  double time_scale = 1;                 // bench seconds per wall second (an emulator's speed-up)
  // One device request's round trip (wall seconds), for duration estimates and the dwell's pace
  // of encoder readings (one per frame unless a round trip at the speed-up is longer than a frame
  // period): at a speed-up it costs that many times more bench time (0: not counted; the
  // emulator's is set for it).
  double link_round_trip_s = 0;
  double poll_interval_s = 0.002;        // wall seconds between gimbal polls when no sensor frame paces them
  // The gimbal starts moves at a set time of its clock (docs/icd.md, the scheduled move): what the
  // dry run's estimate assumes. The engine itself asks the connected gimbal (Gimbal::timed_moves).
  bool timed_moves = false;
  // The reference's own calibration (the stand file's `reference:`): the engine forms each row's
  // reference angles from true_from_reading of the encoders; the rows keep the raw readings as
  // gimbal_pitch/yaw_arcsec. Unset: the readings are taken as true.
  std::optional<ReferenceCalibration> reference;

  // Physical seconds -> wall seconds to wait.
  double wall(double physical_s) const { return physical_s / time_scale; }
};

nlohmann::json to_json(const EngineSettings& b);

}  // namespace fpss
