// The procedure engine: runs a plan on a gimbal and a sensor, owns timeouts, re-measurement, pause, abort and the safe stop.
#pragma once
#include <atomic>
#include <chrono>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <spdlog/logger.h>

#include "drivers/gimbal.h"
#include "drivers/sensor.h"
#include "procedures/settings.h"
#include "procedures/plan.h"
#include "procedures/align.h"
#include "procedures/events.h"
#include "procedures/recorder.h"

namespace fpss {

// Set from signal handlers or another thread; the engine looks at them between and inside waits.
struct RunControl {
  std::atomic<bool> abort{false};   // SIGINT/SIGTERM or the operator: stop, return to null, mark interrupted
  std::atomic<bool> pause{false};   // hold between points (gimbal at the last point) until cleared (SIGUSR1, keys)
  std::atomic<int> signal{0};       // the signal that asked for the abort, for the log
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
  // A check action: returns an empty string when the limits hold, else what broke them.
  std::function<std::string(const Action&)> check;
  // A diagnose action: the sim-to-real diagnosis of what was recorded before it. Throwing fails the run.
  std::function<void(const Action&)> diagnose;
  // A point of a grid with an adaptive stop is about to be measured: the live fit's largest
  // 1-sigma (arcsec) over the range of the point's group and axes; infinite when it cannot tell.
  std::function<double(const Action&)> until_sigma;
};

class Engine {
 public:
  // Every point's rows are published as a Samples event: subscribe a RunRecorder (record_with)
  // before run(), or nothing is kept. `from` says where a resumed run continues.
  Engine(Gimbal& gimbal, Sensor& sensor, const EngineSettings& bench, const Plan& plan, EventBus& events,
         spdlog::logger& log, RunControl& control, EngineHooks hooks = {}, ResumePoint from = {});

  // Runs the plan from `from.next_point` (0 for a new run).
  // `session` is 1 + the number of resumes, written in each row.
  EngineResult run(int session = 1);
  const EngineStats& stats() const { return stats_; }

 private:
  struct PointFailure : std::runtime_error {
    explicit PointFailure(const std::string& what, StopCause c = StopCause::other)
        : std::runtime_error(what), cause(c) {}
    StopCause cause;
  };
  struct Aborted {};

  void prepare();
  void do_action(size_t index);  // plan_.actions[index], skipping what a resumed run did before
  // True when plan_.actions[index] belongs to an adaptive-stop group that has reached its target
  // (the group's points left are then journalled as skipped, once).
  bool until_reached(size_t index);
  void do_home(const Action& a);
  // A computation step (calibrate, diagnose) through its hook; what it throws stops the run with `cause`.
  void compute(const Action& a, const char* what, const std::function<void(const Action&)>& hook, StopCause cause);
  void do_move(const Action& a);
  void measure_dwell(const Action& a, int session);
  // A dwell's frames and the encoder readings they are referenced to (ref_of: each frame's reading).
  struct DwellFrames {
    std::vector<SensorSample> frames;
    std::vector<GimbalState> refs;
    std::vector<size_t> ref_of;
    int invalid = 0;  // frames skipped as invalid
  };
  DwellFrames take_dwell(const Action& a, const GimbalState& arrived);
  // Waits out the settle after the arrival; the dwell's first frame when the frames told.
  std::optional<SensorSample> settle(const Action& a, const GimbalState& arrived, double& settled_host_s);
  std::optional<SensorSample> next_dwell_frame(std::optional<SensorSample>& first);
  // GimbalFailure unless the gimbal is still at `a`'s point, unfaulted and not moving.
  void check_still(const Action& a, const GimbalState& st, const char* when);
  // Puts the scheduled next move back to `start_s` (a dwell lengthened by an invalid frame, or
  // begun later than the frame grid said); PointFailure if it has begun already.
  void reschedule_next_move(const Action& a, double& move_at_s, double start_s);
  void measure_slew(const Action& a, int session);
  // Each slew frame's time on the sensor's clock and the same instant on the gimbal's clock.
  void slew_times(const std::vector<SensorSample>& frames, const std::vector<GimbalFix>& fixes,
                  std::vector<double>& s_times, std::vector<double>& g_times) const;
  // Runs attempt(1), attempt(2), ... until one succeeds or the stand's re-measurements run out.
  void with_remeasure(const Action& a, const std::function<void(int)>& attempt);
  // Moves and waits until a reading finds the gimbal in position; arrived_s_ is then when it got
  // there (docs/procedures.md, "How the engine waits"), which settles count from.
  GimbalState move_and_wait(double pitch, double yaw, double timeout_physical_s, bool homing = false);
  void sleep_physical(double physical_s);
  // The bench clock (the devices' own) now: the latest device time stamp, advanced by the host
  // clock since at the bench's pace.
  double bench_now_s() const;
  double bench_now_at(double host_s) const;
  void note_bench(double bench_s, double host_s);
  // Waits until the bench clock reaches t_s: the host clock for the part surely ahead, then (one
  // clock for both devices) the sensor's time-stamped frames. Returns the first frame at or after
  // t_s when the frames told, nullopt when the host clock did (another clock, a silent sensor).
  std::optional<SensorSample> wait_bench_until(double t_s);
  void sleep_until_bench(double t_s);
  // Commands the move of the action after the current one while this point is still being
  // stored (its fsync overlaps the motion); move_and_wait then only waits for it.
  void command_next_move();
  // With a gimbal that starts moves at a set time of its clock: the next point's move, scheduled
  // to start at start_s (bench clock) from `a`'s point; the start, or nullopt when not scheduled.
  std::optional<double> schedule_next_move(const Action& a, double start_s);
  // The same for a move queued while the gimbal travelled to `a` (queue_move_after_next), put
  // back to start_s if the frames came later than predicted; `arrived`, the reading that found
  // the gimbal there, started it if it came after the move's time.
  std::optional<double> adopt_queued_move(const Action& a, double start_s, const GimbalState& arrived);
  // After a dwell, with the next move scheduled: the move after it, scheduled behind the next one
  // for the end of its dwell, so the host has that whole move, settle and dwell in hand.
  void queue_move_after_next();
  void send_move_at(const Action& n, double start_s);  // n's move, to start at start_s (bench clock)
  // A move at a set time the gimbal refused: in good time when a reading after it says the start
  // was still to come and the gimbal unfaulted, so that it cannot take such a move (not a host too
  // late, nor a fault; not either when it does not answer), and the gimbal's words.
  struct MoveRefused {
    bool in_good_time = false;
    std::string why;
  };
  // send_move_at; what the refusal says when the gimbal refuses.
  std::optional<MoveRefused> schedule_move(const Action& n, double start_s);
  // Reads the gimbal until the pending move has begun (a few looks at most): the reading that
  // says so, or nullopt.
  std::optional<GimbalState> wait_move_begun(double start_s);
  void schedule_pending(const Action& n, const Action& from, double start_s);
  // The action `ahead` after the current one if its move may be commanded now (one that is a
  // dwell, with all between them dwells).
  const Action* dwell_to_command(size_t ahead = 1) const;
  // The first frame at or after t_s on the sensor's frame grid (one clock for both devices).
  double first_frame_from(double t_s) const;
  // When a dwell of `a` whose first frame is at first_frame_s ends: half a frame period after its
  // last frame, when the move after it is scheduled to start.
  double dwell_end_s(const Action& a, double first_frame_s) const;
  void drop_moves_ahead();  // forgets the moves commanded or scheduled ahead (the gimbal was stopped)
  // Stops the gimbal, which cancels a scheduled move (one under way stops where it is), and
  // forgets the moves ahead.
  void call_off_moves_ahead();
  void set_pending(const Action& n, double start_lo_s, double dur_s, double start_hi_s, bool scheduled);
  double move_s(double from_pitch_arcsec, double from_yaw_arcsec, const Action& to) const;  // profile duration
  // Excludes a computation step's bench time from EngineStats::bench_s.
  void off_bench(const std::function<void()>& f);
  void wait_while_paused();
  void check_abort();
  void recover(const std::string& reason, bool sensor_side);
  // Publishes the rows (the recorder makes them durable), then PointDone.
  void publish_point(const Action& a, const std::vector<RecordedRow>& rows, int attempt, int session, int invalid);
  void warn(const Action* a, const std::string& message);
  // Every command the engine sends goes through these, so it knows what the gimbal should hold.
  void command_rate(double arcsec_s);
  void command_move(double pitch_arcsec, double yaw_arcsec);
  // The targets this run last wrote to the gimbal, which verify_command reads back.
  void targets_written(double pitch_arcsec, double yaw_arcsec);
  // Reads the gimbal's commanded state back; GimbalFailure (commanded_elsewhere) when another
  // client changed a target, the rate, the watchdog, or put it in rate mode.
  void verify_command();
  bool safe_stop();
  double stand_time(double sensor_time_s);
  double sensor_clock_s(const SensorSample& f) const;
  double host_now_s() const;
  double session_host_s(double host_s) const { return host_s - host_t0_; }
  GimbalState read_gimbal();
  // The sensor's temperature for point `a`'s rows; NaN (and a warning) when it does not answer.
  double read_temperature_c(const Action& a);
  // The gimbal reading a row is referenced to (stand frame) and the gimbal-clock time it stands for.
  struct GimbalRef {
    double time_s = 0, pitch_arcsec = 0, yaw_arcsec = 0;
    uint16_t status = 0;
  };
  // One row of point `a`: frame `f` at `sensor_time_s` (sensor clock) with its reference `g`.
  RecordedRow make_row(const Action& a, Phase phase, const SensorSample& f, double sensor_time_s, const GimbalRef& g,
                       double temperature_c, int attempt, int session);

  Gimbal& g_;
  Sensor& s_;
  const EngineSettings& b_;
  const Plan& plan_;
  EventBus& events_;
  ResumePoint from_;
  int64_t next_point_ = 0;  // points durable so far (all sessions)
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
  bool moved_ = false;
  GimbalCommand commanded_;
  bool target_known_ = false;
  bool stopping_ = false;  // during the safe stop an abort request no longer interrupts
  bool timed_moves_refused_ = false;  // the gimbal refused a scheduled move in time: not asked again
  bool queue_refused_ = false;        // the same for a scheduled move behind one under way
  bool late_for_schedule_ = false;    // the last scheduled dwell could not be read before its move began
  double host_t0_ = 0;
  // Stand time: base + (sensor time - sensor t0), kept non-decreasing across sensor restarts.
  std::optional<double> sensor_t0_;
  double time_base_ = 0, last_time_ = 0;
  double last_gimbal_time_s_ = 0;
  double arrived_s_ = 0;  // the last move's arrival (bench clock), however late a reading saw it
  // A frame's time (shared clock): the sensor's frames come on a grid of its period from it.
  double frame_grid_s_ = std::numeric_limits<double>::quiet_NaN();
  double last_pitch_arcsec_ = 0, last_yaw_arcsec_ = 0;  // the latest encoder reading
  double last_bench_s_ = 0, last_bench_host_s_ = 0;     // the latest device time stamp and its receipt
  double bench_start_s_ = -1, off_bench_s_ = 0;
  size_t action_ = 0;           // plan_.actions index being done
  // A move commanded ahead (command_next_move): its target and predicted arrival (bench clock),
  // from the latest stamp before the command (the first look, never late) and from the bench
  // time once the command was surely sent (the latest it can arrive if it follows its profile).
  struct PendingMove {
    double pitch_arcsec = 0, yaw_arcsec = 0, arrival_s = 0, arrival_latest_s = 0;
    double start_s = 0;      // no later than the motion's start: the arrival's lower bound
    bool scheduled = false;  // started by the gimbal's clock at start_s (Gimbal::move_at)
  };
  std::optional<PendingMove> pending_;
  // The move after the pending one, scheduled behind it: its action and its start (bench clock).
  struct QueuedMove {
    size_t action = 0;
    double start_s = 0;
  };
  std::optional<QueuedMove> queued_;
};

}  // namespace fpss
