// The engine's waiting on the bench clock: the clock from the devices' time stamps, waits that end
// on the sensor's frames, moves predicted from the gimbal's profile, the next move commanded early.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "procedures/engine.h"
#include "procedures/engine_detail.h"

namespace fpss {

using namespace engine_detail;

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

void Engine::note_bench(double bench_s, double host_s) {
  // The devices' stamps are the truth (the host's estimate between them may run ahead); never
  // backwards: a late stamp of an earlier instant says nothing new.
  if (bench_s >= last_bench_s_) {
    last_bench_s_ = bench_s;
    last_bench_host_s_ = host_s;
  }
}

double Engine::bench_now_at(double host_s) const {
  if (last_bench_host_s_ <= 0) return last_bench_s_;
  return last_bench_s_ + std::max(0.0, host_s - last_bench_host_s_) * b_.time_scale;
}

double Engine::bench_now_s() const { return bench_now_at(host_now_s()); }

void Engine::sleep_until_bench(double t_s) { sleep_physical(t_s - bench_now_s()); }

std::optional<SensorSample> Engine::wait_bench_until(double t_s) {
  // The gimbal's watchdog (bench seconds) wants a request in time: a longer wait is cut by readings.
  const double keep_alive = 0.5 * b_.watchdog_s;
  while (keep_alive > 0 && t_s - last_gimbal_time_s_ > keep_alive + 1e-6) {  // (the inner wait: none)
    const double before = last_gimbal_time_s_;
    wait_bench_until(before + keep_alive);
    check_abort();
    read_gimbal();
    if (last_gimbal_time_s_ <= before) break;  // a gimbal clock standing still paces nothing
  }
  const double period = 1.0 / b_.sample_rate_hz;
  if (last_bench_s_ >= t_s) return std::nullopt;  // a device already said it is past
  if (b_.clock != ClockSync::shared) {
    sleep_until_bench(t_s);
    return std::nullopt;
  }
  // The host clock for what is surely ahead (two frame periods short), then the frames: their
  // time stamps are the bench clock itself, whatever the host's scheduler did.
  sleep_until_bench(t_s - 2 * period);
  const double frame_wait = b_.wall(period) + b_.frame_timeout_s;
  for (;;) {
    check_abort();
    std::optional<SensorSample> f;
    try {
      Timed t(stats_.device_s);
      f = s_.next_sample(frame_wait);
    } catch (const DeviceError&) {
      f.reset();  // the measurement that needs the sensor says so; the wait falls back on the host clock
    }
    if (!f) {
      sleep_until_bench(t_s);
      return std::nullopt;
    }
    const double ts = sensor_clock_s(*f);
    note_bench(ts, f->host_time_s);
    frame_grid_s_ = ts;
    if (ts + 1e-9 >= t_s) return f;
  }
}

void Engine::off_bench(const std::function<void()>& f) {
  // From the latest device stamp before (nothing of the bench's happens after it: the gimbal
  // rests where the last point left it, and the host stores that point) to a gimbal reading after.
  struct Add {
    Engine& e;
    double t0;
    ~Add() {
      double t1 = 0;
      try {
        e.read_gimbal();
        t1 = e.last_bench_s_;
      } catch (const std::exception&) {
        t1 = e.bench_now_s();
      }
      e.off_bench_s_ += std::max(0.0, t1 - t0);
    }
  } add{*this, last_bench_s_};
  f();
}

GimbalState Engine::move_and_wait(double pitch, double yaw, double timeout_physical_s, bool homing) {
  const double rate = commanded_.max_rate_arcsec_s > 0 ? commanded_.max_rate_arcsec_s : b_.profile_rate_arcsec_s;
  double arrival = 0;         // when the profile says the gimbal arrives (bench clock): the next look
  double arrival_latest = 0;  // the same from the latest instant the motion can have started
  double on_its_way_s = 0;    // the last instant known to be before the arrival
  if (!homing && pending_ && pending_->pitch_arcsec == pitch && pending_->yaw_arcsec == yaw) {
    arrival = pending_->arrival_s;  // commanded, or scheduled, while the last point was measured
    arrival_latest = pending_->arrival_latest_s;
    on_its_way_s = pending_->start_s;
  } else {
    drop_moves_ahead();  // the command below cancels any scheduled move
    // From the latest device time stamp (no later than the command): the first look may come
    // early, never late.
    const double from_p = last_pitch_arcsec_, from_y = last_yaw_arcsec_, t0 = last_bench_s_;
    on_its_way_s = t0;
    Timed t(stats_.device_s);
    moved_ = true;
    if (homing) {
      g_.home();
      commanded_.target_pitch_arcsec = commanded_.target_yaw_arcsec = 0;
      target_known_ = false;  // a home need not write the target registers
    }
    else command_move(pitch, yaw);
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
    check_abort();
    wait_bench_until(arrival);
    st = read_gimbal();
    if (st.has(kFault) || st.fault != GimbalFault::none) {
      throw GimbalFailure(fmt::format("gimbal fault ({}) while moving to pitch {}, yaw {}", fault_name(st),
                                      deg(pitch), deg(yaw)));
    }
    const bool there = homing ? st.has(kHomed)
                              : std::fabs(st.pitch_arcsec - pitch) <= tol && std::fabs(st.yaw_arcsec - yaw) <= tol;
    if (there && st.has(kInPosition) && !st.has(kMoving)) {
      // A settle counts from the arrival, not from when the host came to look (a late look, by a
      // frame, a round trip or a busy host, would lengthen every settle): the profile's arrival
      // from a known start (a scheduled move's) or from a reading in motion (its position and
      // speed), within what the readings bracket; without either, the reading that found it there.
      arrived_s_ = std::min(std::max(arrival_latest, on_its_way_s), last_gimbal_time_s_);
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
    on_its_way_s = last_gimbal_time_s_;
    arrival = last_gimbal_time_s_ + std::max(left, floor_s);
    arrival_latest = last_gimbal_time_s_ + left;
  }
}

const Action* Engine::dwell_to_command(size_t ahead) const {
  // A pause or an abort holds the gimbal where it is.
  if (ctl_.pause.load() || ctl_.abort.load() || action_ + ahead >= plan_.actions.size()) return nullptr;
  for (size_t i = action_ + 1; i <= action_ + ahead; ++i) {
    const Action& n = plan_.actions[i];
    if (n.kind != Action::Kind::dwell || n.point < cursor_.first) return nullptr;
    // A point of an adaptive-stop group is decided on the fit that includes the point now ending.
    if (n.until_group >= 0) return nullptr;
  }
  return &plan_.actions[action_ + ahead];
}

double Engine::first_frame_from(double t_s) const {
  const double period_s = 1.0 / b_.sample_rate_hz;
  return frame_grid_s_ + std::ceil((t_s - frame_grid_s_) / period_s - 1e-6) * period_s;
}

double Engine::dwell_end_s(const Action& a, double first_frame_s) const {
  return first_frame_s + (a.frames - 0.5) * (1.0 / b_.sample_rate_hz);
}

void Engine::drop_moves_ahead() {
  pending_.reset();
  queued_.reset();
}

void Engine::call_off_moves_ahead() {
  drop_moves_ahead();
  try {
    Timed t(stats_.device_s);
    g_.stop();
  } catch (const DeviceError& e) {
    log_.warn("the moves scheduled ahead could not be called off: {}", e.what());
  }
}

void Engine::set_pending(const Action& n, double start_lo_s, double dur_s, double start_hi_s, bool scheduled) {
  targets_written(n.pitch_arcsec, n.yaw_arcsec);
  moved_ = true;
  pending_ = PendingMove{n.pitch_arcsec, n.yaw_arcsec, start_lo_s + dur_s, start_hi_s + dur_s, start_lo_s, scheduled};
}

double Engine::move_s(double from_p, double from_y, const Action& to) const {
  const double rate = commanded_.max_rate_arcsec_s > 0 ? commanded_.max_rate_arcsec_s : b_.profile_rate_arcsec_s;
  return move_duration_s(from_p, from_y, to.pitch_arcsec, to.yaw_arcsec, rate, b_.acceleration_arcsec_s2);
}

std::optional<double> Engine::schedule_next_move(const Action& a, double start_s) {
  const bool schedule = g_.timed_moves() && !timed_moves_refused_ && !late_for_schedule_;
  const Action* n = schedule ? dwell_to_command() : nullptr;
  if (!n) return std::nullopt;
  if (const auto refused = schedule_move(*n, start_s)) {
    // Too late (the host was away past the start), or a gimbal that cannot, which is not asked
    // again this run. Either way the move is commanded when this dwell ends.
    if (refused->in_good_time) {
      timed_moves_refused_ = true;
      log_.warn("the gimbal refused a scheduled move ({}); each move is commanded when its dwell ends", refused->why);
    } else {
      log_.debug("{}: move not scheduled in time ({})", label(*n), refused->why);
    }
    return std::nullopt;
  }
  schedule_pending(*n, a, start_s);
  ++stats_.scheduled_moves;
  return start_s;
}

std::optional<double> Engine::adopt_queued_move(const Action& a, double start_s, const GimbalState& arrived) {
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

void Engine::queue_move_after_next() {
  queued_.reset();
  const bool can = g_.timed_moves() && !timed_moves_refused_ && !queue_refused_ && pending_ &&
                   pending_->scheduled && b_.clock == ClockSync::shared && std::isfinite(frame_grid_s_);
  const Action* n = can ? dwell_to_command(2) : nullptr;
  if (!n) return;
  const Action& next = plan_.actions[action_ + 1];
  const double start_s = dwell_end_s(next, first_frame_from(pending_->arrival_s + next.settle_s));
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
      log_.info("the gimbal takes no move behind one under way ({}); each is scheduled at its arrival", refused->why);
    }
    return;
  }
  targets_written(n->pitch_arcsec, n->yaw_arcsec);
  queued_ = QueuedMove{action_ + 2, start_s};
  ++stats_.scheduled_moves;
}

void Engine::send_move_at(const Action& n, double start_s) {
  Timed t(stats_.device_s);
  g_.move_at(n.pitch_arcsec, n.yaw_arcsec, static_cast<uint64_t>(std::llround(start_s * 1e6)));
}

std::optional<Engine::MoveRefused> Engine::schedule_move(const Action& n, double start_s) {
  try {
    send_move_at(n, start_s);
    return std::nullopt;
  } catch (const DeviceError& e) {
    MoveRefused r{false, e.what()};
    target_known_ = false;  // the targets may have been written
    try {
      const GimbalState st = read_gimbal();
      r.in_good_time = last_gimbal_time_s_ < start_s && st.fault == GimbalFault::none && !st.has(kFault);
    } catch (const DeviceError&) {
      // not in good time: the dwell's own readings will say what the link does
    }
    return r;
  }
}

std::optional<GimbalState> Engine::wait_move_begun(double start_s) {
  for (int look = 0; look < 8; ++look) {
    sleep_until_bench(start_s);
    const GimbalState st = read_gimbal();
    // Arrived already (a short move): this reading saw it there, and a move scheduled now could
    // start before the host has measured the point; the dwell schedules it instead.
    if (!st.has(kMovePending)) return st.has(kMoving) ? std::optional<GimbalState>(st) : std::nullopt;
    start_s = last_gimbal_time_s_ + 0.25 / b_.sample_rate_hz;
  }
  return std::nullopt;
}

void Engine::schedule_pending(const Action& n, const Action& from, double start_s) {
  // The gimbal's own clock starts it: the arrival is the profile's from that instant, exactly.
  set_pending(n, start_s, move_s(from.pitch_arcsec, from.yaw_arcsec, n), start_s, true);
}

void Engine::command_next_move() {
  if (pending_ && pending_->scheduled) {
    // A pause or an abort asked for during the dwell: the scheduled move is called off (a stop
    // cancels it; if it has begun, the gimbal stops where it is and the next move starts afresh).
    if (ctl_.pause.load() || ctl_.abort.load()) call_off_moves_ahead();
    return;
  }
  drop_moves_ahead();
  const Action* n = dwell_to_command();
  if (!n) return;
  const double from_p = last_pitch_arcsec_, from_y = last_yaw_arcsec_, t0 = last_bench_s_;
  try {
    Timed t(stats_.device_s);
    command_move(n->pitch_arcsec, n->yaw_arcsec);
  } catch (const DeviceError& e) {
    log_.debug("{}: move commanded ahead not sent ({}); sent again when its turn comes", label(*n), e.what());
    target_known_ = false;
    return;
  }
  set_pending(*n, t0, move_s(from_p, from_y, *n), kUnknown, false);
}

}  // namespace fpss
