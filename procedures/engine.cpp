#include "procedures/engine.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <ctime>
#include <limits>
#include <thread>

#include <sys/prctl.h>

#include "procedures/align.h"
#include "procedures/engine_detail.h"

namespace fpss {

using namespace engine_detail;


Engine::Engine(Gimbal& gimbal, Sensor& sensor, const EngineSettings& bench, const Plan& plan, EventBus& events,
               spdlog::logger& log, RunControl& control, EngineHooks hooks, ResumePoint from)
    : g_(gimbal), s_(sensor), b_(bench), plan_(plan), events_(events), from_(std::move(from)),
      next_point_(from_.next_point), log_(log), ctl_(control), hooks_(std::move(hooks)) {}

void Engine::warn(const Action* a, const std::string& message) {
  log_.warn("{}", message);
  events_.publish(Fault{Fault::Level::warning, a && a->is_point() ? a->point : -1, message});
}

void Engine::publish_point(const Action& a, const std::vector<RecordedRow>& rows, int attempt, int session,
                           int invalid) {
  try {
    Timed t(stats_.storage_s);
    events_.publish(Samples{&a, &rows, attempt, session});
  } catch (const std::exception& e) {
    throw StorageFailure(e.what());
  }
  next_point_ = a.point + 1;
  ++stats_.points;
  events_.publish(PointDone{&a, &rows, PointStats::of(rows), attempt, invalid});
}

double Engine::host_now_s() const {
  // The drivers stamp receipts with the same steady clock (SensorSample/GimbalState::host_time_s).
  return std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
}

void Engine::check_abort() {
  if (stopping_) return;
  if (ctl_.abort.load()) throw Aborted{};
}

GimbalState Engine::read_gimbal() {
  GimbalState st;
  {
    Timed t(stats_.device_s);
    st = g_.read_state();
  }
  last_gimbal_time_s_ = static_cast<double>(st.sample_time_us) * 1e-6;
  last_pitch_arcsec_ = st.pitch_arcsec;
  last_yaw_arcsec_ = st.yaw_arcsec;
  note_bench(last_gimbal_time_s_, st.host_time_s > 0 ? st.host_time_s : host_now_s());
  if (bench_start_s_ < 0) bench_start_s_ = last_gimbal_time_s_;
  return st;
}

double Engine::read_temperature_c(const Action& a) {
  try {
    Timed t(stats_.device_s);
    return s_.temperature_c();
  } catch (const DeviceError& e) {
    log_.warn("point {}: no temperature ({})", a.point + 1, e.what());
    return std::numeric_limits<double>::quiet_NaN();
  }
}

RecordedRow Engine::make_row(const Action& a, Phase phase, const SensorSample& f, double sensor_time_s,
                             const GimbalRef& g, double temperature_c, int attempt, int session) {
  const auto [ref_a, ref_b] = b_.axes.sensor_from_stand(g.pitch_arcsec, g.yaw_arcsec);
  RecordedRow r;
  r.sensor_time_s = sensor_time_s;
  r.sample = Sample{stand_time(sensor_time_s), phase, a.point + 1, ref_a, ref_b,
                    static_cast<double>(f.counts_alpha), static_cast<double>(f.counts_beta)};
  r.frame_seq = f.seq;
  r.sensor_status = f.status;
  r.host_time_s = session_host_s(f.host_time_s);
  r.gimbal_time_s = g.time_s;
  r.gimbal_pitch_arcsec = g.pitch_arcsec;
  r.gimbal_yaw_arcsec = g.yaw_arcsec;
  r.gimbal_status = g.status;
  r.target_pitch_arcsec = a.pitch_arcsec;
  r.target_yaw_arcsec = a.yaw_arcsec;
  r.temperature_c = temperature_c;
  r.attempt = attempt;
  r.session = session;
  return r;
}

void Engine::command_rate(double arcsec_s) {
  g_.set_max_rate(arcsec_s);
  commanded_.max_rate_arcsec_s = arcsec_s;
}

void Engine::command_move(double pitch_arcsec, double yaw_arcsec) {
  g_.move_to(pitch_arcsec, yaw_arcsec);
  targets_written(pitch_arcsec, yaw_arcsec);
}

void Engine::targets_written(double pitch_arcsec, double yaw_arcsec) {
  commanded_.target_pitch_arcsec = pitch_arcsec;
  commanded_.target_yaw_arcsec = yaw_arcsec;
  target_known_ = true;
}

void Engine::verify_command() {
  std::optional<GimbalCommand> c;
  try {
    Timed t(stats_.device_s);
    c = g_.read_command();
  } catch (const DeviceError& e) {
    throw GimbalFailure(e.what());
  }
  if (!c) return;
  // The registers hold whole milliarcseconds (and ms for the watchdog): allow their rounding.
  const double mas = 1e-3 * 1.01;
  std::string what;
  auto differs = [&](const char* name, double read, double wrote, double tol, const char* unit) {
    if (std::fabs(read - wrote) > tol) what += fmt::format("{}{} {} {} (this run wrote {})", what.empty() ? "" : ", ", name, read, unit, wrote);
  };
  if (target_known_) {
    differs("pitch target", c->target_pitch_arcsec, commanded_.target_pitch_arcsec, mas, "arcsec");
    differs("yaw target", c->target_yaw_arcsec, commanded_.target_yaw_arcsec, mas, "arcsec");
  }
  if (commanded_.max_rate_arcsec_s > 0) differs("max rate", c->max_rate_arcsec_s, commanded_.max_rate_arcsec_s, mas, "arcsec/s");
  differs("watchdog", c->watchdog_s, commanded_.watchdog_s, 1.01e-3, "s");
  if (c->command == 5) what += fmt::format("{}rate mode commanded", what.empty() ? "" : ", ");
  if (!what.empty()) {
    throw GimbalFailure(fmt::format("gimbal commanded by another client: {}", what), StopCause::commanded_elsewhere);
  }
}

void Engine::sleep_physical(double physical_s) {
  const double wall = b_.wall(physical_s);
  if (wall <= 0) return;
  Timed t(stats_.sleep_s);
  const auto end = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(wall));
  while (Clock::now() < end) {
    check_abort();
    const Clock::duration left = end - Clock::now();
    std::this_thread::sleep_for(std::min<Clock::duration>(left, std::chrono::milliseconds(20)));
  }
}

void Engine::wait_while_paused() {
  if (!ctl_.pause.load()) return;
  log_.info("paused at the last point; the gimbal holds (the key r, or SIGUSR1 again, continues)");
  // Moves scheduled ahead would start during the pause (the next point commands its move afresh).
  if (pending_ || queued_) call_off_moves_ahead();
  events_.publish(Paused{next_point_});
  while (ctl_.pause.load()) {
    check_abort();
    read_gimbal();  // keeps the link (and a watchdog) alive
    Timed t(stats_.sleep_s);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  log_.info("continuing");
  events_.publish(Resumed{next_point_});
}

double Engine::sensor_clock_s(const SensorSample& f) const {
  const double t = b_.clock == ClockSync::shared ? unwrap_near(f.sensor_time_us, last_gimbal_time_s_)
                                                 : f.sensor_time_s;
  return std::round((t + b_.sensor_time_offset_s) * 1e6) / 1e6;
}

double Engine::stand_time(double sensor_time_s) {
  if (!sensor_t0_) sensor_t0_ = sensor_time_s;
  double t = time_base_ + (sensor_time_s - *sensor_t0_);
  if (t < last_time_) {
    // The sensor's clock restarted (a power cycle, a new link): continue from the last time.
    time_base_ = last_time_;
    sensor_t0_ = sensor_time_s;
    t = last_time_;
  }
  // Whole microseconds, as the devices count them: no 0.020000000000000018 in the recording.
  t = std::round(t * 1e6) / 1e6;
  last_time_ = t;
  return t;
}

namespace {
// Seconds since an ISO 8601 UTC time (2024-05-01T12:00:00Z); 0 when it cannot be read.
double seconds_since_utc(const std::string& iso) {
  std::tm tm{};
  if (iso.empty() || !strptime(iso.c_str(), "%Y-%m-%dT%H:%M:%SZ", &tm)) return 0;
  const std::time_t then = timegm(&tm);
  return std::max(0.0, std::difftime(std::time(nullptr), then));
}
}  // namespace

void Engine::prepare() {
  host_t0_ = host_now_s();
  time_base_ = last_time_ = from_.last_time_s;
  if (!from_.last_utc.empty()) {
    // A resume: the stand's time went on while the run was down (at the bench's pace).
    time_base_ += seconds_since_utc(from_.last_utc) * b_.time_scale;
  }
  GimbalState st = read_gimbal();
  Timed t(stats_.device_s);
  if (st.has(kFault) || st.fault != GimbalFault::none) {
    log_.warn("gimbal reports a fault ({}) at the start: clearing it", fault_name(st));
    g_.clear_fault();
  }
  command_rate(b_.profile_rate_arcsec_s);
  g_.set_watchdog(b_.watchdog_s);
  commanded_.watchdog_s = b_.watchdog_s;
  s_.set_rate(static_cast<int>(std::lround(b_.sample_rate_hz)));
  s_.start();
}

void Engine::recover(const std::string& reason, bool sensor_side) {
  ++stats_.recoveries;
  drop_moves_ahead();  // the gimbal is stopped below: a move commanded ahead is void
  // A short pause lets a dropped link come back (the drivers reconnect on the next request).
  sleep_physical(0);
  {
    Timed t(stats_.sleep_s);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  try {
    GimbalState st = read_gimbal();
    Timed t(stats_.device_s);
    // Whoever changed them, the stand's settings are written back.
    if (commanded_.max_rate_arcsec_s > 0) command_rate(commanded_.max_rate_arcsec_s);
    g_.set_watchdog(commanded_.watchdog_s);
    if (st.has(kFault) || st.fault != GimbalFault::none) {
      warn(nullptr, fmt::format("clearing gimbal fault ({})", fault_name(st)));
      g_.clear_fault();
    } else if (st.has(kMoving) || st.has(kMovePending)) {
      g_.stop();
    }
  } catch (const DeviceError& e) {
    log_.warn("gimbal not answering while recovering: {}", e.what());
  }
  if (sensor_side) {
    try {
      Timed t(stats_.device_s);
      log_.warn("restarting the sensor stream");
      s_.stop();
      s_.flush();
      s_.start();
    } catch (const DeviceError& e) {
      log_.warn("sensor not answering while recovering: {}", e.what());
    }
  }
}

void Engine::with_remeasure(const Action& a, const std::function<void(int)>& attempt_fn) {
  std::string reason;
  StopCause cause = StopCause::other;
  const int attempts = 1 + std::max(0, b_.max_remeasure);
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    bool sensor_side = false;
    try {
      if (a.is_point()) events_.publish(PointStarted{&a, attempt});
      attempt_fn(attempt);
      if (attempt > 1) log_.info("{} done on attempt {}", label(a), attempt);
      return;
    } catch (const SensorFailure& e) {
      reason = e.what();
      cause = e.cause;
      sensor_side = true;
    } catch (const GimbalFailure& e) {
      reason = e.what();
      cause = e.cause;
    } catch (const PointFailure& e) {
      reason = e.what();
      cause = e.cause;
    } catch (const LimitError&) {
      throw;  // refused before the wire: retrying cannot help
    } catch (const DeviceError& e) {
      reason = e.what();
      cause = StopCause::other;
      sensor_side = true;  // not knowing which device failed, reset both
    }
    warn(&a, fmt::format("{} attempt {}/{} not counted: {}", label(a), attempt, attempts, reason));
    check_abort();
    if (attempt < attempts) {
      ++stats_.remeasured;
      recover(reason, sensor_side);
    }
  }
  throw PointFailure(fmt::format("{} failed after {} attempts: {}",
                                 a.is_point() ? a.describe() : fmt::format("{} ({})", label(a), a.describe()), attempts,
                                 reason),
                     cause);
}

void Engine::compute(const Action& a, const char* what, const std::function<void(const Action&)>& hook,
                     StopCause cause) {
  log_.info("step {}: {}", a.step_index, what);
  if (!hook) return;
  Timed t(stats_.calibrate_s);
  try {
    hook(a);
  } catch (const std::exception& e) {
    throw PointFailure(e.what(), cause);
  }
}

void Engine::do_home(const Action& a) {
  const double timeout = a.timeout_s > 0 ? a.timeout_s : b_.home_timeout_s;
  with_remeasure(a, [&](int) { move_and_wait(0, 0, timeout, true); });
}

void Engine::do_move(const Action& a) {
  auto go = [&](int) {
    if (a.rate_arcsec_s > 0) {
      Timed t(stats_.device_s);
      command_rate(a.rate_arcsec_s);
    }
    try {
      move_and_wait(a.pitch_arcsec, a.yaw_arcsec, b_.move_timeout_s);
    } catch (...) {
      if (a.rate_arcsec_s > 0) {
        try {
          command_rate(b_.profile_rate_arcsec_s);
        } catch (const DeviceError&) {
        }
      }
      throw;
    }
    if (a.rate_arcsec_s > 0) {
      Timed t(stats_.device_s);
      command_rate(b_.profile_rate_arcsec_s);
    }
  };
  with_remeasure(a, go);
}

bool Engine::safe_stop() {
  stopping_ = true;
  drop_moves_ahead();
  bool ok = true;
  try {
    Timed t(stats_.device_s);
    g_.stop();
  } catch (const DeviceError& e) {
    ok = false;
    log_.error("safe stop: gimbal stop failed: {}", e.what());
  }
  if (moved_) {
    // Up to a few attempts: the fault that stopped the run may need clearing first.
    for (int attempt = 1; attempt <= 3; ++attempt) {
      try {
        GimbalState st = read_gimbal();
        if (st.has(kFault) || st.fault != GimbalFault::none) {
          Timed t(stats_.device_s);
          g_.clear_fault();
        }
        {
          Timed t(stats_.device_s);
          command_rate(b_.profile_rate_arcsec_s);
        }
        move_and_wait(0, 0, b_.move_timeout_s);
        log_.info("gimbal back at null");
        ok = true;
        break;
      } catch (const std::exception& e) {
        ok = false;
        log_.error("safe stop: return to null, attempt {}: {}", attempt, e.what());
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
      }
    }
  }
  try {
    Timed t(stats_.device_s);
    s_.stop();
  } catch (const DeviceError& e) {
    log_.warn("safe stop: sensor stop failed: {}", e.what());
  }
  stopping_ = false;
  return ok;
}

void Engine::do_action(size_t i) {
  const Action& a = plan_.actions[i];
  action_ = i;
  const bool done_before = cursor_.resuming && i < cursor_.resume_at;
  switch (a.kind) {
    case Action::Kind::home:
      if (done_before) {
        // After a restart the axes may need homing again; once is enough.
        if (!cursor_.homed_again && cursor_.resume_at < plan_.actions.size()) {
          do_home(a);
          cursor_.homed_again = true;
        }
        break;
      }
      log_.info("step {}: home", a.step_index);
      do_home(a);
      break;
    case Action::Kind::move:
      if (done_before) break;
      log_.info("step {}: {}", a.step_index, a.describe());
      do_move(a);
      break;
    case Action::Kind::settle:
      if (done_before) break;
      wait_bench_until(bench_now_s() + a.settle_s);
      break;
    case Action::Kind::dwell:
      if (a.point < cursor_.first) break;
      log_.debug("step {}: {}", a.step_index, a.describe());
      measure_dwell(a, cursor_.session);
      break;
    case Action::Kind::slew:
      if (a.point < cursor_.first) break;
      log_.info("step {}: {}", a.step_index, a.describe());
      measure_slew(a, cursor_.session);
      break;
    case Action::Kind::calibrate:
      off_bench([&] { compute(a, "calibrate", hooks_.calibrate, StopCause::calibration_failed); });
      break;
    case Action::Kind::diagnose:
      off_bench([&] { compute(a, "diagnose", hooks_.diagnose, StopCause::diagnosis_failed); });
      break;
    case Action::Kind::check: {
      log_.info("step {}: check", a.step_index);
      std::string broken;
      if (hooks_.check) off_bench([&] { broken = hooks_.check(a); });
      if (!broken.empty()) {
        throw PointFailure(fmt::format("step {} (check): {}", a.step_index, broken), StopCause::check_failed);
      }
      break;
    }
  }
}

bool Engine::until_reached(size_t index) {
  const Action& a = plan_.actions[index];
  if (a.until_group < 0) return false;
  auto& done = cursor_.until_done;
  if (std::find(done.begin(), done.end(), a.until_group) != done.end()) return true;
  if (!a.is_point() || a.point < cursor_.first || !hooks_.until_sigma) return false;
  double sigma;
  {
    Timed t(stats_.calibrate_s);
    sigma = hooks_.until_sigma(a);
  }
  if (!(sigma <= a.until_sigma_arcsec)) return false;
  done.push_back(a.until_group);
  StepStopped ev;
  ev.step_index = a.step_index;
  ev.axes = a.until_both_axes ? "both" : to_string(a.axis);
  ev.sigma_max_arcsec = sigma;
  ev.until_sigma_arcsec = a.until_sigma_arcsec;
  ev.session = cursor_.session;
  for (size_t j = index; j < plan_.actions.size(); ++j) {
    const Action& b = plan_.actions[j];
    if (b.until_group == a.until_group && b.is_point()) ev.skipped.push_back(b.point);
  }
  log_.info("step {}: adaptive stop on {}: largest 1-sigma {:.4f} <= {:.4f} arcsec; {} points not measured",
            a.step_index, ev.axes, sigma, a.until_sigma_arcsec, ev.skipped.size());
  try {
    Timed t(stats_.storage_s);
    events_.publish(ev);
  } catch (const std::exception& e) {
    throw StorageFailure(e.what());
  }
  next_point_ = ev.skipped.back() + 1;
  return true;
}

EngineResult Engine::run(int session) {
  const auto t0 = Clock::now();
  // Waits of tens of microseconds matter at a fast emulator's pace (a microsecond of wall time is
  // a millisecond of bench time at 1000x): no timer slack on this thread while the run lasts.
  struct TimerSlack {
    int prev = ::prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0);
    TimerSlack() { ::prctl(PR_SET_TIMERSLACK, 1, 0, 0, 0); }
    ~TimerSlack() {
      if (prev > 0) ::prctl(PR_SET_TIMERSLACK, prev, 0, 0, 0);
    }
  } slack;
  bench_start_s_ = -1;
  off_bench_s_ = 0;
  EngineResult r;
  cursor_ = Cursor{};
  cursor_.session = session;
  cursor_.first = from_.next_point;
  cursor_.resuming = cursor_.first > 0;
  // Actions before the first point still to measure were done in an earlier session (except
  // calibrate and check, which are computations and run again on the same data).
  cursor_.resume_at = cursor_.first < static_cast<int64_t>(plan_.points) ? plan_.point_action[cursor_.first]
                                                                         : plan_.actions.size();
  try {
    prepare();
    // Bench time counts from here, as the plan's physical minimum does: the link's setup (the
    // sensor's rate and start, the gimbal's rate and watchdog: round trips, a few ms of wall time,
    // seconds of bench time at 1000x) is not the procedure's.
    bench_start_s_ = -1;
    read_gimbal();
    events_.publish(RunStarted{session, cursor_.first, &plan_});
    if (cursor_.resuming) log_.info("resuming at point {} of {}", cursor_.first + 1, plan_.points);
    for (size_t i = 0; i < plan_.actions.size(); ++i) {
      check_abort();
      wait_while_paused();
      if (until_reached(i)) continue;
      do_action(i);
    }
    r.outcome = RunOutcome::completed;
  } catch (const Aborted&) {
    r.outcome = RunOutcome::interrupted;
    const int sig = ctl_.signal.load();
    r.cause = sig ? StopCause::interrupted : StopCause::aborted;
    r.reason = sig ? fmt::format("interrupted by signal {} ({})", sig, strsignal(sig)) : "aborted by the operator";
  } catch (const PointFailure& e) {
    r.outcome = RunOutcome::failed;
    r.cause = e.cause;
    r.reason = e.what();
  } catch (const LimitError& e) {
    r.outcome = RunOutcome::failed;
    r.cause = StopCause::limit;
    r.reason = e.what();
  } catch (const StorageFailure& e) {
    r.outcome = RunOutcome::failed;
    r.cause = StopCause::storage;
    r.reason = e.what();
  } catch (const std::exception& e) {
    r.outcome = RunOutcome::failed;
    r.cause = StopCause::other;
    r.reason = e.what();
  }
  if (r.outcome != RunOutcome::completed) log_.error("run {}: {}", to_string(r.outcome), r.reason);
  r.safe_state = safe_stop();
  if (!r.safe_state) {
    log_.error("the gimbal could not be returned to null: check the stand");
    if (r.outcome == RunOutcome::completed) {
      r.outcome = RunOutcome::failed;
      r.cause = StopCause::unsafe;
      r.reason = "the gimbal could not be returned to null at the end";
    }
  }
  r.points_done = next_point_;
  if (bench_start_s_ >= 0) {
    const double bench = std::max(0.0, last_bench_s_ - bench_start_s_ - off_bench_s_);
    stats_.bench_s += bench;
    log_.info("bench time {:.2f} s (computation steps left out); the plan's physical minimum {:.2f} s, estimate {:.2f} s",
              bench, plan_.physical_s, plan_.estimated_s);
  }
  events_.publish(RunStopped{r.outcome, r.cause, r.reason, r.points_done, r.safe_state});
  stats_.wall_s += seconds_since(t0);
  return r;
}

}  // namespace fpss
