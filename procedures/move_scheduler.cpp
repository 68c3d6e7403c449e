#include "procedures/move_scheduler.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

#include "procedures/engine_detail.h"

namespace fpss {

using namespace engine_detail;

MoveScheduler::MoveScheduler(EngineIo& io, EngineClock& clock, const Plan& plan)
    : io_(io), clock_(clock), b_(io.settings()), plan_(plan), stats_(io.stats()) {}

namespace {
constexpr double kUnknown = std::numeric_limits<double>::infinity();

// Seconds an axis needs to stop at a target `e` away, moving at `v` now, with the profile's
// top speed and acceleration (the trapezoid of move_duration_s, entered part-way).
double axis_remaining_s(double e, double v, double vmax, double acc) {
  if (e < 0) {
    e = -e;
    v = -v;
  }
  if (e <= 0 || !(vmax > 0)) return 0;
  if (!(acc > 0)) return e / vmax;
  if (v < 0) return -v / acc + move_duration_s(0, 0, e + v * v / (2 * acc), 0, vmax, acc);  // stops first
  if (v * v / (2 * acc) >= e) return v > 0 ? 2 * e / v : 0;                                   // braking onto it
  const double vp = std::min(vmax, std::sqrt(acc * e + v * v / 2));
  const double cruise = e - (vp * vp - v * v) / (2 * acc) - vp * vp / (2 * acc);
  return (vp - v) / acc + std::max(0.0, cruise) / vp + vp / acc;
}
}  // namespace

void MoveScheduler::sleep_physical(double physical_s) {
  const double wall = b_.wall(physical_s);
  if (wall <= 0) return;
  Timed t(stats_.sleep_s);
  const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(wall));
  while (Clock::now() < end) {
    io_.check_abort();
    const Clock::duration left = end - Clock::now();
    std::this_thread::sleep_for(std::min<Clock::duration>(left, std::chrono::milliseconds(20)));
  }
}

void MoveScheduler::sleep_until_bench(double t_s) { sleep_physical(t_s - clock_.bench_now_s()); }

std::optional<SensorSample> MoveScheduler::wait_bench_until(double t_s) {
  // The gimbal's watchdog (bench seconds) wants a request in time: a longer wait is cut by readings.
  const double keep_alive = 0.5 * b_.watchdog_s;
  while (keep_alive > 0 && t_s - clock_.last_gimbal_s() > keep_alive + 1e-6) {  // (the inner wait: none)
    const double before = clock_.last_gimbal_s();
    wait_bench_until(before + keep_alive);
    io_.check_abort();
    io_.read_gimbal();
    if (clock_.last_gimbal_s() <= before) break;  // a gimbal clock standing still paces nothing
  }
  const double period = 1.0 / b_.sample_rate_hz;
  if (clock_.last_bench_s() >= t_s) return std::nullopt;  // a device already said it is past
  if (b_.clock != ClockSync::shared) {
    sleep_until_bench(t_s);
    return std::nullopt;
  }
  // The host clock for what is surely ahead (two frame periods short), then the frames: their
  // time stamps are the bench clock itself, whatever the host's scheduler did.
  sleep_until_bench(t_s - 2 * period);
  const double frame_wait = b_.wall(period) + b_.frame_timeout_s;
  for (;;) {
    io_.check_abort();
    std::optional<SensorSample> f;
    try {
      Timed t(stats_.device_s);
      f = io_.sensor().next_sample(frame_wait);
    } catch (const DeviceError&) {
      f.reset();  // the measurement that needs the sensor says so; the wait falls back on the host clock
    }
    if (!f) {
      sleep_until_bench(t_s);
      return std::nullopt;
    }
    const double ts = clock_.sensor_clock_s(*f);
    clock_.note_bench(ts, f->host_time_s);
    clock_.note_frame(ts);
    if (ts + 1e-9 >= t_s) return f;
  }
}

void MoveScheduler::note_motion(double from_pitch, double from_yaw, double to_pitch, double to_yaw) {
  const double from[2] = {rest_known_ ? rest_[0] : from_pitch, rest_known_ ? rest_[1] : from_yaw};
  const double to[2] = {to_pitch, to_yaw};
  const double still = 2 * b_.in_position_tolerance_arcsec;
  const bool moved[2] = {std::fabs(to[0] - from[0]) > still, std::fabs(to[1] - from[1]) > still};
  // A move that moves no axis (a dwell re-commanding its point) is none: the last real one stands.
  if (moved[0] || moved[1]) {
    for (int a = 0; a < 2; ++a) dir_[a] = moved[a] ? (to[a] > from[a] ? 1 : -1) : 0;
  }
  for (int a = 0; a < 2; ++a) rest_[a] = to[a];
  rest_known_ = true;
}

GimbalState MoveScheduler::move_and_wait(double pitch, double yaw, double timeout_physical_s, bool homing) {
  const double rate = io_.move_rate_arcsec_s();
  const double entry_pitch = io_.last_pitch_arcsec(), entry_yaw = io_.last_yaw_arcsec();
  double arrival = 0;         // when the profile says the gimbal arrives (bench clock): the next look
  double arrival_latest = 0;  // the same from the latest instant the motion can have started
  double on_its_way_s = 0;    // the last instant known to be before the arrival
  // Already sent there and arrived (a move step, then a settle, then a dwell at the same place): when
  // a reading finds it still there, nothing is sent and the arrival stays the move's, so the time
  // since the move and the settle count from it; else it is sent there again.
  bool stay = !homing && arrived_target_ && (*arrived_target_)[0] == pitch && (*arrived_target_)[1] == yaw;
  if (stay && !pending_) {
    const GimbalState st = io_.read_gimbal();
    const double tol = b_.in_position_tolerance_arcsec;
    if (st.has(kInPosition) && !st.has(kMoving) && st.fault == GimbalFault::none && !st.has(kFault) &&
        std::fabs(st.pitch_arcsec - pitch) <= tol && std::fabs(st.yaw_arcsec - yaw) <= tol) {
      note_motion(entry_pitch, entry_yaw, st.pitch_arcsec, st.yaw_arcsec);
      return st;
    }
    stay = false;
  }
  if (!homing && pending_ && pending_->pitch_arcsec == pitch && pending_->yaw_arcsec == yaw) {
    arrival = pending_->arrival_s;  // commanded, or scheduled, while the last point was measured
    arrival_latest = pending_->arrival_latest_s;
    on_its_way_s = pending_->start_s;
  } else {
    drop_moves_ahead();  // the command below cancels any scheduled move
    arrived_target_.reset();
    // From the latest device time stamp (no later than the command): the first look may come
    // early, never late.
    const double from_p = io_.last_pitch_arcsec(), from_y = io_.last_yaw_arcsec(), t0 = clock_.last_bench_s();
    on_its_way_s = t0;
    Timed t(stats_.device_s);
    io_.mark_moved();
    if (homing) io_.command_home();
    else io_.command_move(pitch, yaw);
    const double dur = move_duration_s(from_p, from_y, homing ? 0 : pitch, homing ? 0 : yaw, rate, b_.acceleration_arcsec_s2);
    arrival = t0 + dur;
    arrival_latest = kUnknown;  // when the command reached the gimbal no stamp can tell
  }
  pending_.reset();
  // Communication slack on top of the physical time: a slow link must not look like a stuck axis.
  const double timeout_wall = b_.wall(timeout_physical_s) + 2.0;
  const auto start = Clock::now();
  const double tol = b_.in_position_tolerance_arcsec;
  GimbalState st;
  for (;;) {
    io_.check_abort();
    wait_bench_until(arrival);
    st = io_.read_gimbal();
    if (st.has(kFault) || st.fault != GimbalFault::none) {
      throw GimbalFailure(fmt::format("gimbal fault ({}) while moving to pitch {}, yaw {}", fault_name(st),
                                      deg(pitch), deg(yaw)));
    }
    const bool there = homing ? st.has(kHomed)
                              : std::fabs(st.pitch_arcsec - pitch) <= tol && std::fabs(st.yaw_arcsec - yaw) <= tol;
    if (!there) io_.check_commanded_place(st);  // not on its way from this run's commands: stop
    if (there && st.has(kInPosition) && !st.has(kMoving)) {
      // A settle counts from the arrival, not from when the host came to look (a late look, by a
      // frame, a round trip or a busy host, would lengthen every settle): the profile's arrival
      // from a known start (a scheduled move's) or from a reading in motion (its position and
      // speed), within what the readings bracket; without either, the reading that found it there.
      if (!stay) arrived_s_ = std::min(std::max(arrival_latest, on_its_way_s), clock_.last_gimbal_s());
      if (homing) arrived_target_.reset();
      else arrived_target_ = std::array<double, 2>{pitch, yaw};
      note_motion(entry_pitch, entry_yaw, st.pitch_arcsec, st.yaw_arcsec);
      return st;
    }
    if (seconds_since(start) > timeout_wall) {
      throw GimbalFailure(fmt::format("gimbal not in position at pitch {}, yaw {} within {:.1f} s (at pitch {}, yaw "
                                      "{}, status 0x{:02x})",
                                      deg(pitch), deg(yaw), timeout_wall, deg(st.pitch_arcsec), deg(st.yaw_arcsec),
                                      st.status));
    }
    // Not there yet: when it will be, from where it is and how fast it goes; no sooner than the
    // next frame (or the stand's poll interval without a shared clock).
    const double left = std::max(axis_remaining_s(pitch - st.pitch_arcsec, st.pitch_rate_arcsec_s, rate, b_.acceleration_arcsec_s2),
                                 axis_remaining_s(yaw - st.yaw_arcsec, st.yaw_rate_arcsec_s, rate, b_.acceleration_arcsec_s2));
    const double floor_s = b_.clock == ClockSync::shared ? 0.0 : b_.poll_interval_s * b_.time_scale;
    on_its_way_s = clock_.last_gimbal_s();
    arrival = clock_.last_gimbal_s() + std::max(left, floor_s);
    arrival_latest = clock_.last_gimbal_s() + left;
  }
}

const Action* MoveScheduler::dwell_to_command(size_t ahead) const {
  // A pause or an abort holds the gimbal where it is.
  if (io_.control().pause.load() || io_.control().abort.load() || action_ + ahead >= plan_.actions.size()) return nullptr;
  for (size_t i = action_ + 1; i <= action_ + ahead; ++i) {
    const Action& n = plan_.actions[i];
    if (n.kind != Action::Kind::dwell || n.point < first_point_) return nullptr;
    // A point of an adaptive-stop group is decided on the fit that includes the point now ending.
    if (n.until_group >= 0) return nullptr;
  }
  return &plan_.actions[action_ + ahead];
}

void MoveScheduler::drop_moves_ahead() {
  pending_.reset();
  queued_.reset();
}

void MoveScheduler::call_off_moves_ahead() {
  drop_moves_ahead();
  arrived_target_.reset();  // a move begun stops where it is
  try {
    Timed t(stats_.device_s);
    io_.gimbal().stop();
    const GimbalState st = io_.read_gimbal();
    io_.note_place(st.pitch_arcsec, st.yaw_arcsec);  // a move begun stops about here
  } catch (const DeviceError& e) {
    io_.log().warn("the moves scheduled ahead could not be called off: {}", e.what());
  }
}

void MoveScheduler::set_pending(const Action& n, double start_lo_s, double dur_s, double start_hi_s, bool scheduled) {
  // Sent elsewhere (or there again): the gimbal is no longer known to rest where it arrived.
  if (!arrived_target_ || (*arrived_target_)[0] != n.pitch_arcsec || (*arrived_target_)[1] != n.yaw_arcsec) {
    arrived_target_.reset();
  }
  io_.targets_written(n.pitch_arcsec, n.yaw_arcsec);
  io_.mark_moved();
  pending_ = PendingMove{n.pitch_arcsec, n.yaw_arcsec, start_lo_s + dur_s, start_hi_s + dur_s, start_lo_s, scheduled};
}

double MoveScheduler::move_s(double from_p, double from_y, const Action& to) const {
  const double rate = io_.move_rate_arcsec_s();
  return move_duration_s(from_p, from_y, to.pitch_arcsec, to.yaw_arcsec, rate, b_.acceleration_arcsec_s2);
}

std::optional<double> MoveScheduler::schedule_next_move(const Action& a, double start_s) {
  const bool schedule = io_.gimbal().timed_moves() && !timed_moves_refused_ && !late_for_schedule_;
  const Action* n = schedule ? dwell_to_command() : nullptr;
  if (!n) return std::nullopt;
  if (const auto refused = schedule_move(*n, start_s)) {
    // Too late (the host was away past the start), or a gimbal that cannot, which is not asked
    // again this run. Either way the move is commanded when this dwell ends.
    if (refused->in_good_time) {
      timed_moves_refused_ = true;
      io_.log().warn("the gimbal refused a scheduled move ({}); each move is commanded when its dwell ends", refused->why);
    } else {
      io_.log().debug("{}: move not scheduled in time ({})", label(*n), refused->why);
    }
    return std::nullopt;
  }
  schedule_pending(*n, a, start_s);
  ++stats_.scheduled_moves;
  return start_s;
}

void MoveScheduler::reschedule_next_move(const Action& a, double& move_at_s, double start_s) {
  // Only if it has not started (a reading says: still pending), else the point is measured again.
  move_at_s = start_s;
  pending_.reset();
  GimbalState st;
  try {
    send_move_at(plan_.actions[action_ + 1], move_at_s);
    st = io_.read_gimbal();
  } catch (const DeviceError& e) {
    throw PointFailure(fmt::format("the next move, scheduled for the dwell's end, could not be put back: {}", e.what()));
  }
  if (!st.has(kMovePending)) throw PointFailure("the next move had started before the dwell's last frame");
  io_.check_still(a, st, "while");
  schedule_pending(plan_.actions[action_ + 1], a, move_at_s);
}

std::optional<double> MoveScheduler::adopt_queued_move(const Action& a, double start_s, const GimbalState& arrived) {
  const QueuedMove q = *queued_;
  queued_.reset();
  // (A queued move of another dwell cannot be left after a recovery, which drops it; if one were,
  // scheduling afresh replaces it on the gimbal.)
  if (q.action != action_ + 1) return schedule_next_move(a, start_s);
  const Action& n = plan_.actions[q.action];
  const double seen_s = static_cast<double>(arrived.sample_time_us) * 1e-6;
  if (seen_s >= q.start_s) {
    // The host read this point only after the move's time: the gimbal waited for that reading
    // (docs/icd.md) and started then. The dwell's frames came before; that reading is their reference.
    set_pending(n, seen_s, move_s(a.pitch_arcsec, a.yaw_arcsec, n), seen_s, true);
    return q.start_s;
  }
  schedule_pending(n, a, q.start_s);
  double move_at_s = q.start_s;
  if (start_s > q.start_s + 1e-6) reschedule_next_move(a, move_at_s, start_s);
  return move_at_s;
}

void MoveScheduler::queue_move_after_next() {
  queued_.reset();
  const bool can = io_.gimbal().timed_moves() && !timed_moves_refused_ && !queue_refused_ && pending_ &&
                   pending_->scheduled && b_.clock == ClockSync::shared && clock_.frame_grid_known();
  const Action* n = can ? dwell_to_command(2) : nullptr;
  if (!n) return;
  const Action& next = plan_.actions[action_ + 1];
  const double start_s = clock_.dwell_end_s(next, clock_.first_frame_from(pending_->arrival_s + next.settle_s));
  // The gimbal queues a move behind one under way; one still pending it would replace.
  std::optional<GimbalState> begun;
  try {
    begun = wait_move_begun(pending_->start_s);
  } catch (const DeviceError&) {
    return;  // the next dwell's readings will say what the link does
  }
  if (!begun) return;
  if (const auto refused = schedule_move(*n, start_s)) {
    // Refused in good time: a gimbal that schedules only from rest, not asked again this run.
    if (refused->in_good_time) {
      queue_refused_ = true;
      io_.log().info("the gimbal takes no move behind one under way ({}); each is scheduled at its arrival", refused->why);
    }
    return;
  }
  io_.targets_written(n->pitch_arcsec, n->yaw_arcsec);
  queued_ = QueuedMove{action_ + 2, start_s};
  ++stats_.scheduled_moves;
}

void MoveScheduler::send_move_at(const Action& n, double start_s) {
  Timed t(stats_.device_s);
  io_.gimbal().move_at(n.pitch_arcsec, n.yaw_arcsec, static_cast<uint64_t>(std::llround(start_s * 1e6)));
}

std::optional<MoveScheduler::MoveRefused> MoveScheduler::schedule_move(const Action& n, double start_s) {
  try {
    send_move_at(n, start_s);
    return std::nullopt;
  } catch (const DeviceError& e) {
    MoveRefused r{false, e.what()};
    io_.targets_unknown();  // the targets may have been written
    try {
      const GimbalState st = io_.read_gimbal();
      r.in_good_time = clock_.last_gimbal_s() < start_s && st.fault == GimbalFault::none && !st.has(kFault);
    } catch (const DeviceError&) {
      // not in good time: the dwell's own readings will say what the link does
    }
    return r;
  }
}

std::optional<GimbalState> MoveScheduler::wait_move_begun(double start_s) {
  for (int look = 0; look < 8; ++look) {
    sleep_until_bench(start_s);
    const GimbalState st = io_.read_gimbal();
    // Arrived already (a short move): this reading saw it there, and a move scheduled now could
    // start before the host has measured the point; the dwell schedules it instead.
    if (!st.has(kMovePending)) return st.has(kMoving) ? std::optional<GimbalState>(st) : std::nullopt;
    start_s = clock_.last_gimbal_s() + 0.25 / b_.sample_rate_hz;
  }
  return std::nullopt;
}

void MoveScheduler::schedule_pending(const Action& n, const Action& from, double start_s) {
  // The gimbal's own clock starts it: the arrival is the profile's from that instant, exactly.
  set_pending(n, start_s, move_s(from.pitch_arcsec, from.yaw_arcsec, n), start_s, true);
}

void MoveScheduler::command_next_move() {
  if (pending_ && pending_->scheduled) {
    // A pause or an abort asked for during the dwell: the scheduled move is called off (a stop
    // cancels it; if it has begun, the gimbal stops where it is and the next move starts afresh).
    if (io_.control().pause.load() || io_.control().abort.load()) call_off_moves_ahead();
    return;
  }
  drop_moves_ahead();
  const Action* n = dwell_to_command();
  if (!n) return;
  const double from_p = io_.last_pitch_arcsec(), from_y = io_.last_yaw_arcsec(), t0 = clock_.last_bench_s();
  try {
    Timed t(stats_.device_s);
    io_.command_move(n->pitch_arcsec, n->yaw_arcsec);
  } catch (const DeviceError& e) {
    io_.log().debug("{}: move commanded ahead not sent ({}); sent again when its turn comes", label(*n), e.what());
    io_.targets_unknown();
    return;
  }
  set_pending(*n, t0, move_s(from_p, from_y, *n), kUnknown, false);
}

}  // namespace fpss
