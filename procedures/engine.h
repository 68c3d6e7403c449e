// The procedure engine: runs a plan on a gimbal and a sensor, owns timeouts, re-measurement, pause, abort and the safe stop.
#pragma once
#include <atomic>
#include <chrono>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <spdlog/logger.h>

#include "drivers/gimbal.h"
#include "drivers/sensor.h"
#include "procedures/settings.h"
#include "procedures/plan.h"
#include "procedures/align.h"
#include "procedures/check_report.h"
#include "procedures/events.h"
#include "procedures/recorder.h"

namespace fpss {

// Set from signal handlers or another thread; the engine looks at them between and inside waits.
struct RunControl {
  std::atomic<bool> abort{false};   // SIGINT/SIGTERM or the operator: stop, return to null, mark interrupted
  std::atomic<bool> pause{false};   // hold between points (gimbal at the last point) until cleared (SIGUSR1, keys)
  std::atomic<int> signal{0};       // the signal that asked for the abort, for the log
};

// One sensor unit the engine reads: several share the gimbal's readings (docs/procedures.md,
// "Several units"). `id` is the unit's index in the stand's list, written in each row (RecordedRow::unit).
struct EngineUnit {
  int id = 0;
  Sensor* sensor = nullptr;  // borrowed
  AxisMapping axes;          // how it sits on the gimbal
  std::string serial{};      // as it reported itself ("": unknown), for the messages that name it
  // Its own sensor options (the stand file's sensors entry; NaN: the engine's settings). The lead's
  // rate paces the dwells: a unit that takes the lead is set to the first unit's rate.
  double sample_rate_hz = std::numeric_limits<double>::quiet_NaN();
  double frame_timeout_s = std::numeric_limits<double>::quiet_NaN();
  double sensor_time_offset_s = std::numeric_limits<double>::quiet_NaN();
};
// A unit dropped from the run: why, and at which point (0-based; -1 before the first).
struct UnitLoss {
  int unit = 0;
  LossCause cause = LossCause::silence;
  std::string reason;
  int64_t point = -1;
};

struct EngineResult {
  RunOutcome outcome = RunOutcome::completed;
  StopCause cause = StopCause::none;
  std::string reason;         // why it failed or stopped, for people
  int64_t points_done = 0;    // completed points in the recording (all sessions)
  bool safe_state = true;     // the gimbal was stopped and returned to null (or was never moved)
};

// Where the controller's own time goes, to compare with the time spent waiting on devices.
struct EngineStats {
  double wall_s = 0;         // total in run()
  double device_s = 0;       // inside device calls (I/O and the devices' own waiting)
  double sleep_s = 0;        // settle times and poll intervals
  double storage_s = 0;      // appending and syncing samples.csv and the journal (fsync)
  double calibrate_s = 0;    // computation steps: calibrate and diagnose (not per point)
  // Bench seconds (the devices' clock) from the first reading to the gimbal back at null, the
  // computation steps left out: what the plan's estimated_s (the physical minimum) predicts.
  double bench_s = 0;
  int64_t points = 0;        // points measured in this session
  int64_t remeasured = 0;    // extra attempts
  int64_t recoveries = 0;    // fault clears, stream restarts
  int64_t scheduled_moves = 0;  // moves the gimbal started on its own clock (Gimbal::move_at)
  // The controller's own work: everything but waiting on devices, sleeping, the disk's fsync and fits.
  double own_s() const { return wall_s - device_s - sleep_s - storage_s - calibrate_s; }
};

// Calibrate and check steps run outside the engine (they are computation on the recording).
struct EngineHooks {
  // A calibrate action: fit what was recorded before it. Throwing fails the run.
  std::function<void(const Action&)> calibrate;
  // A check action: what the limits found, unit by unit; one that did not pass stops the run
  // (StopCause::check_failed).
  std::function<CheckReport(const Action&)> check;
  // A diagnose action: the sim-to-real diagnosis of what was recorded before it. Throwing fails the run.
  std::function<void(const Action&)> diagnose;
  // A point of a grid with an adaptive stop is about to be measured: the live fit's largest
  // 1-sigma (arcsec) over the range of the point's group and axes; infinite when it cannot tell.
  std::function<double(const Action&)> until_sigma;
  // Several units: a unit was dropped (the session stops fitting and diagnosing it from here on).
  std::function<void(const UnitLoss&)> unit_lost;
};

class EngineClock;
class EngineIo;
class MoveScheduler;
class PointMeasurer;

// Runs the plan: its actions in order, pause, abort and the safe stop. Measuring a point
// (PointMeasurer), moving and waiting on bench time (MoveScheduler) and estimating that time
// (EngineClock) are parts it owns; they share the devices through one EngineIo.
class Engine {
 public:
  // Every point's rows are published as a Samples event: subscribe a RunRecorder (record_with)
  // before run(), or nothing is kept. `from` says where a resumed run continues.
  Engine(Gimbal& gimbal, Sensor& sensor, const EngineSettings& bench, const Plan& plan, EventBus& events,
         spdlog::logger& log, RunControl& control, EngineHooks hooks = {}, ResumePoint from = {});
  ~Engine();
  // Its parts hold references to each other and to its statistics.
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  // Several units on the one gimbal: replaces the constructor's single sensor (unit 0 on the
  // settings' axes) before run(). The first is the lead: its frames pace the dwells; the others'
  // frames are taken over the same dwell and referenced to the same gimbal readings. A unit that
  // fails is dropped (EngineHooks::unit_lost) and the others go on; the lead's place passes to the next.
  void set_units(std::vector<EngineUnit> units);

  // Runs the plan from `from.next_point` (0 for a new run).
  // `session` is 1 + the number of resumes, written in each row.
  EngineResult run(int session = 1);
  const EngineStats& stats() const { return stats_; }

 private:
  void prepare();
  void do_action(size_t index);  // plan_.actions[index], skipping what a resumed run did before
  // True when plan_.actions[index] belongs to an adaptive-stop group that has reached its target
  // (the group's points left are then journalled as skipped, once).
  bool until_reached(size_t index);
  void do_home(const Action& a);
  // A computation step (calibrate, diagnose) through its hook; what it throws stops the run with `cause`.
  void compute(const Action& a, const char* what, const std::function<void(const Action&)>& hook, StopCause cause);
  void do_move(const Action& a);
  // Excludes a computation step's bench time from EngineStats::bench_s.
  void off_bench(const std::function<void()>& f);
  void wait_while_paused();
  bool safe_stop();

  const EngineSettings& b_;
  const Plan& plan_;
  EventBus& events_;
  ResumePoint from_;
  spdlog::logger& log_;
  RunControl& ctl_;
  EngineHooks hooks_;
  EngineStats stats_;
  // Where this run() is in the plan.
  struct Cursor {
    int session = 1;
    int64_t first = 0;      // first point still to measure
    bool resuming = false;
    size_t resume_at = 0;   // index of that point's action
    bool homed_again = false;
    std::vector<int> until_done;  // adaptive-stop groups that reached their target
  } cursor_;
  std::unique_ptr<EngineClock> clock_;
  std::unique_ptr<EngineIo> io_;
  std::unique_ptr<MoveScheduler> scheduler_;
  std::unique_ptr<PointMeasurer> measurer_;
};

}  // namespace fpss
