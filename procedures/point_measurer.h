// The engine's measurement of a point: a dwell or a slew, its settle, its re-measurement, and publishing its rows.
#pragma once
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <spdlog/logger.h>

#include "drivers/gimbal.h"
#include "drivers/sensor.h"
#include "procedures/align.h"
#include "procedures/engine_clock.h"
#include "procedures/engine_io.h"
#include "procedures/events.h"
#include "procedures/move_scheduler.h"
#include "procedures/plan.h"
#include "procedures/recorder.h"

namespace fpss {

// A dwell's frames are at rest, each with its own encoder reading; a slew's are aligned with the
// gimbal's readings by interpolation. Either way a point is durable before it is reported done.
class PointMeasurer {
 public:
  // `next_point`: points durable so far (all sessions).
  PointMeasurer(EngineIo& io, EngineClock& clock, MoveScheduler& scheduler, int64_t next_point);

  void measure_dwell(const Action& a, int session);
  void measure_slew(const Action& a, int session);
  // Runs attempt(1), attempt(2), ... until one succeeds or the stand's re-measurements run out.
  // Several units: a lead failing every attempt on its side is dropped and the next one begins again.
  void with_remeasure(const Action& a, const std::function<void(int)>& attempt);

  int64_t next_point() const { return next_point_; }
  // Points an adaptive stop leaves unmeasured count as done: a resume goes on after them.
  void skip_to(int64_t next_point) { next_point_ = next_point; }

 private:
  // A dwell's frames and the encoder readings they are referenced to (ref_of: each frame's reading).
  struct DwellFrames {
    std::vector<SensorSample> frames;
    std::vector<GimbalState> refs;
    std::vector<size_t> ref_of;
    int invalid = 0;  // frames skipped as invalid
    double settled_bench_s = 0, settled_host_s = 0;  // the settle's end, on the bench's and the host's clocks
  };
  void attempts(const Action& a, const std::function<void(int)>& attempt);  // one lead's attempts
  DwellFrames take_dwell(const Action& a, const GimbalState& arrived);
  // Waits out the settle after the arrival; the dwell's first frame when the frames told.
  std::optional<SensorSample> settle(const Action& a, const GimbalState& arrived, double& settled_host_s);
  std::optional<SensorSample> next_dwell_frame(std::optional<SensorSample>& first);
  // Each slew frame's time on the sensor's clock and the same instant on the gimbal's clock.
  void slew_times(const std::vector<SensorSample>& frames, const std::vector<GimbalFix>& fixes,
                  std::vector<double>& s_times, std::vector<double>& g_times) const;
  // A dwell frame's time since the gimbal's arrival (`arrived`, the reading that found it in
  // position; arrived_s, the arrival on the gimbal's clock that the settle counts from).
  double since_arrival_s(const SensorSample& f, const GimbalState& arrived, double arrived_s) const;
  // A dwell row's approach_pitch/approach_yaw: the scheduler's sides through this unit's mapping.
  void set_approach(RecordedRow& row, const AxisMapping& axes) const;
  void recover(const std::string& reason, bool sensor_side);
  // Publishes the rows (the recorder makes them durable), then PointDone.
  void publish_point(const Action& a, std::vector<RecordedRow> rows, int attempt, int session, int invalid);
  // The gimbal reading a row is referenced to (stand frame) and the gimbal-clock time it stands for.
  struct GimbalRef {
    double time_s = 0, pitch_arcsec = 0, yaw_arcsec = 0;
    uint16_t status = 0;
  };
  // One row of point `a` for unit `u`: frame `f` at `sensor_time_s` (its sensor clock) and
  // `stand_time_s`, with its reference `g`.
  RecordedRow make_row(const Action& a, Phase phase, const SensorSample& f, double sensor_time_s, double stand_time_s,
                       const GimbalRef& g, double temperature_c, int attempt, int session, const EngineUnit& u);
  // A slew's rows for unit `u` from its frames and the gimbal's readings; counts what it skipped.
  std::vector<RecordedRow> slew_rows(const Action& a, const EngineUnit& u, bool lead, const std::vector<SensorSample>& frames,
                                     const std::vector<GimbalFix>& fixes, int attempt, int session, int& invalid,
                                     int& gapped);

  // --- several units: the followers' frames over the lead's point ---
  // A follower's dwell rows: its frames sampled between the settle's end and the lead's dwell end,
  // each referenced to the gimbal reading of the lead frame nearest in time (lead_rows: the lead's).
  std::vector<RecordedRow> follower_dwell(const Action& a, size_t unit, const DwellFrames& d,
                                          const std::vector<RecordedRow>& lead_rows, const GimbalState& arrived,
                                          double arrived_s, int attempt, int session);
  // Every follower's frames queued now (a slew's, after it).
  std::vector<std::vector<SensorSample>> drain_followers();
  void flush_followers();
  // A follower gave no rows at a point: its stream restarted, or it is dropped after too many in a row.
  void follower_failed(const Action& a, size_t unit, const std::string& why, int invalid);
  void follower_ok(size_t unit);
  // Why a unit is dropped: a line its driver gave up reopening is link_failed; more bad CRCs since
  // its last good point than the point's frames is a CRC storm; else invalid frames when some
  // came; else silence.
  LossCause loss_cause(size_t unit, uint64_t new_crc_errors, const Action& a, bool invalid) const;
  uint64_t crc_errors(size_t unit) const;  // its driver's count so far (0 when it cannot say)
  std::vector<uint64_t> crc_seen_;  // per unit: its driver's CRC errors at its last good point

  EngineIo& io_;
  EngineClock& clock_;
  std::vector<FrameTakenClock> follower_taken_;  // host clocks: each further unit's own link, by unit index
  MoveScheduler& sched_;
  const EngineSettings& b_;
  EventBus& events_;
  spdlog::logger& log_;
  EngineStats& stats_;
  int64_t next_point_ = 0;
};

}  // namespace fpss
