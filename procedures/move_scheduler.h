// The engine's moves and waits on bench time: a move and its arrival, the next moves commanded or scheduled ahead of the dwell that ends.
#pragma once
#include <array>
#include <utility>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "drivers/gimbal.h"
#include "drivers/sensor.h"
#include "procedures/engine_clock.h"
#include "procedures/engine_io.h"
#include "procedures/plan.h"

namespace fpss {

// docs/procedures.md, "How the engine waits": the engine waits on the bench's own clock, and has
// the gimbal leave each point when its dwell ends, whatever the host is doing.
class MoveScheduler {
 public:
  MoveScheduler(EngineIo& io, EngineClock& clock, const Plan& plan);

  // The first point a run still measures: moves are commanded ahead to its points only.
  void set_first_point(int64_t first) { first_point_ = first; }
  void set_action(size_t index) { action_ = index; }  // plan.actions[index] is being done

  // Moves and waits until a reading finds the gimbal in position; arrived_s() is then when it got
  // there (docs/procedures.md, "How the engine waits"), which settles count from.
  GimbalState move_and_wait(double pitch, double yaw, double timeout_physical_s, bool homing = false);
  double arrived_s() const { return arrived_s_; }
  // Each stand axis's direction in the last move that moved the gimbal (+1 upwards, -1 downwards,
  // 0 when that move left the axis where it was, or before any): every move and slew leg of the
  // run counts, those between recorded rows too (samples.csv's approach_pitch/approach_yaw, in the
  // sensor's frame). A move of an axis by at most twice the in-position tolerance is none.
  std::pair<int, int> approach() const { return {dir_[0], dir_[1]}; }
  void note_motion(double from_pitch, double from_yaw, double to_pitch, double to_yaw);

  // Waits until the bench clock reaches t_s: the host clock for the part surely ahead, then (one
  // clock for both devices) the sensor's time-stamped frames. Returns the first frame at or after
  // t_s when the frames told, nullopt when the host clock did (another clock, a silent sensor).
  std::optional<SensorSample> wait_bench_until(double t_s);
  void sleep_until_bench(double t_s);
  void sleep_physical(double physical_s);

  // Commands the move of the action after the current one while this point is still being
  // stored (its fsync overlaps the motion); move_and_wait then only waits for it.
  void command_next_move();
  // With a gimbal that starts moves at a set time of its clock: the next point's move, scheduled
  // to start at start_s (bench clock) from `a`'s point; the start, or nullopt when not scheduled.
  std::optional<double> schedule_next_move(const Action& a, double start_s);
  // Whether a move was queued while the gimbal travelled to the current point (queue_move_after_next).
  bool has_queued() const { return queued_.has_value(); }
  // The same as schedule_next_move for that queued move, put back to start_s if the frames came
  // later than predicted; `arrived`, the reading that found the gimbal there, started it if it
  // came after the move's time.
  std::optional<double> adopt_queued_move(const Action& a, double start_s, const GimbalState& arrived);
  // After a dwell, with the next move scheduled: the move after it, scheduled behind the next one
  // for the end of its dwell, so the host has that whole move, settle and dwell in hand.
  void queue_move_after_next();
  // Puts the scheduled next move back to `start_s` (a dwell lengthened by an invalid frame, or
  // begun later than the frame grid said); PointFailure if it has begun already.
  void reschedule_next_move(const Action& a, double& move_at_s, double start_s);
  // The last scheduled dwell could not be read before its move began: the next move is not scheduled.
  void set_late_for_schedule(bool late) { late_for_schedule_ = late; }

  bool has_moves_ahead() const { return pending_ || queued_; }
  void drop_moves_ahead();  // forgets the moves commanded or scheduled ahead (the gimbal was stopped)
  // Stops the gimbal, which cancels a scheduled move (one under way stops where it is), and
  // forgets the moves ahead.
  void call_off_moves_ahead();

 private:
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
  void set_pending(const Action& n, double start_lo_s, double dur_s, double start_hi_s, bool scheduled);
  double move_s(double from_pitch_arcsec, double from_yaw_arcsec, const Action& to) const;  // profile duration

  EngineIo& io_;
  EngineClock& clock_;
  const EngineSettings& b_;
  const Plan& plan_;
  EngineStats& stats_;
  size_t action_ = 0;
  int64_t first_point_ = 0;
  bool timed_moves_refused_ = false;  // the gimbal refused a scheduled move in time: not asked again
  bool queue_refused_ = false;        // the same for a scheduled move behind one under way
  bool late_for_schedule_ = false;
  double arrived_s_ = 0;  // the last move's arrival (bench clock), however late a reading saw it
  // Where that move was sent: a later move there is none (nothing sent, the arrival stands).
  std::optional<std::array<double, 2>> arrived_target_;
  double rest_[2] = {0, 0};  // where the gimbal last came to rest (stand frame, its readings)
  bool rest_known_ = false;
  int dir_[2] = {0, 0};
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
