#include "procedures/engine.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <thread>

#include <sys/prctl.h>

#include "procedures/engine_clock.h"
#include "procedures/engine_detail.h"
#include "procedures/engine_io.h"
#include "procedures/move_scheduler.h"
#include "procedures/point_measurer.h"

namespace fpss {

using namespace engine_detail;

Engine::Engine(Gimbal& gimbal, Sensor& sensor, const EngineSettings& bench, const Plan& plan, EventBus& events,
               spdlog::logger& log, RunControl& control, EngineHooks hooks, ResumePoint from)
    : b_(bench), plan_(plan), events_(events), from_(std::move(from)), log_(log), ctl_(control),
      hooks_(std::move(hooks)),
      clock_(std::make_unique<EngineClock>(bench)),
      io_(std::make_unique<EngineIo>(gimbal, sensor, bench, events, log, control, stats_, *clock_)),
      scheduler_(std::make_unique<MoveScheduler>(*io_, *clock_, plan)),
      measurer_(std::make_unique<PointMeasurer>(*io_, *clock_, *scheduler_, from_.next_point)) {}

Engine::~Engine() = default;

void Engine::wait_while_paused() {
  if (!ctl_.pause.load()) return;
  log_.info("paused at the last point; the gimbal holds (the key r, or SIGUSR1 again, continues)");
  // Moves scheduled ahead would start during the pause (the next point commands its move afresh).
  if (scheduler_->has_moves_ahead()) scheduler_->call_off_moves_ahead();
  events_.publish(Paused{measurer_->next_point(), {}});
  while (ctl_.pause.load()) {
    io_->check_abort();
    io_->read_gimbal();  // keeps the link (and a watchdog) alive
    Timed t(stats_.sleep_s);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  log_.info("continuing");
  events_.publish(Resumed{measurer_->next_point(), {}});
}

void Engine::prepare() {
  clock_->start(from_);
  GimbalState st = io_->read_gimbal();
  Timed t(stats_.device_s);
  if (st.has(kFault) || st.fault != GimbalFault::none) {
    log_.warn("gimbal reports a fault ({}) at the start: clearing it", fault_name(st));
    io_->gimbal().clear_fault();
  }
  io_->command_rate(b_.profile_rate_arcsec_s);
  io_->command_watchdog(b_.watchdog_s);
  for (size_t i = 0; i < io_->units(); ++i) {
    if (io_->lost(i)) continue;
    Sensor& s = *io_->unit(i).sensor;
    try {
      s.set_rate(static_cast<int>(std::lround(io_->rate_hz(i))));
      s.start();
    } catch (const DeviceError& e) {
      // One unit: its failure is the run's. Several: it is dropped unless it was the last.
      // A sensor that does not answer its start is a device failure, which ends an investigation
      // (stand/investigate), not `other`.
      if (io_->units() == 1 || !io_->lose(i, LossCause::link_failed, fmt::format("could not start its stream: {}", e.what()), -1)) {
        throw PointFailure(e.what(), StopCause::sensor_timeout);
      }
    }
  }
}

void Engine::set_units(std::vector<EngineUnit> units) {
  io_->set_units(std::move(units));
  if (hooks_.unit_lost) io_->on_lost(hooks_.unit_lost);
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
  measurer_->with_remeasure(a, [&](int) { scheduler_->move_and_wait(0, 0, timeout, true); });
}

void Engine::do_move(const Action& a) {
  auto go = [&](int) {
    if (a.rate_arcsec_s > 0) {
      Timed t(stats_.device_s);
      io_->command_rate(a.rate_arcsec_s);
    }
    try {
      scheduler_->move_and_wait(a.pitch_arcsec, a.yaw_arcsec, b_.move_timeout_s);
    } catch (...) {
      if (a.rate_arcsec_s > 0) {
        try {
          io_->command_rate(b_.profile_rate_arcsec_s);
        } catch (const DeviceError&) {
        }
      }
      throw;
    }
    if (a.rate_arcsec_s > 0) {
      Timed t(stats_.device_s);
      io_->command_rate(b_.profile_rate_arcsec_s);
    }
  };
  measurer_->with_remeasure(a, go);
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
        e.io_->read_gimbal();
        t1 = e.clock_->last_bench_s();
      } catch (const std::exception&) {
        t1 = e.clock_->bench_now_s();
      }
      e.clock_->add_off_bench(std::max(0.0, t1 - t0));
    }
  } add{*this, clock_->last_bench_s()};
  f();
}

bool Engine::safe_stop() {
  io_->set_stopping(true);
  scheduler_->drop_moves_ahead();
  bool ok = true;
  try {
    Timed t(stats_.device_s);
    io_->gimbal().stop();
  } catch (const DeviceError& e) {
    ok = false;
    log_.error("safe stop: gimbal stop failed: {}", e.what());
  }
  if (io_->moved()) {
    // Up to a few attempts: the fault that stopped the run may need clearing first.
    for (int attempt = 1; attempt <= 3; ++attempt) {
      try {
        GimbalState st = io_->read_gimbal();
        if (st.has(kFault) || st.fault != GimbalFault::none) {
          Timed t(stats_.device_s);
          io_->gimbal().clear_fault();
        }
        {
          Timed t(stats_.device_s);
          io_->command_rate(b_.profile_rate_arcsec_s);
        }
        scheduler_->move_and_wait(0, 0, b_.move_timeout_s);
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
  for (size_t i = 0; i < io_->units(); ++i) {
    if (io_->lost(i)) continue;
    try {
      Timed t(stats_.device_s);
      io_->unit(i).sensor->stop();
    } catch (const DeviceError& e) {
      log_.warn("safe stop: sensor stop failed: {}", e.what());
    }
  }
  io_->set_stopping(false);
  return ok;
}

void Engine::do_action(size_t i) {
  const Action& a = plan_.actions[i];
  scheduler_->set_action(i);
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
      scheduler_->wait_bench_until(clock_->bench_now_s() + a.settle_s);
      break;
    case Action::Kind::dwell:
      if (a.point < cursor_.first) break;
      log_.debug("step {}: {}", a.step_index, a.describe());
      measurer_->measure_dwell(a, cursor_.session);
      break;
    case Action::Kind::slew:
      if (a.point < cursor_.first) break;
      log_.info("step {}: {}", a.step_index, a.describe());
      measurer_->measure_slew(a, cursor_.session);
      break;
    case Action::Kind::calibrate:
      off_bench([&] { compute(a, "calibrate", hooks_.calibrate, StopCause::calibration_failed); });
      break;
    case Action::Kind::diagnose:
      off_bench([&] { compute(a, "diagnose", hooks_.diagnose, StopCause::diagnosis_failed); });
      break;
    case Action::Kind::check: {
      log_.info("step {}: check", a.step_index);
      CheckReport report;
      if (hooks_.check) off_bench([&] { report = hooks_.check(a); });
      if (!report.passed()) {
        throw PointFailure(fmt::format("step {} (check): {}", a.step_index, report.summary()), StopCause::check_failed);
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
  measurer_->skip_to(ev.skipped.back() + 1);
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
  clock_->reset_bench_count();
  EngineResult r;
  cursor_ = Cursor{};
  cursor_.session = session;
  cursor_.first = from_.next_point;
  cursor_.resuming = cursor_.first > 0;
  // Actions before the first point still to measure were done in an earlier session (except
  // calibrate and check, which are computations and run again on the same data).
  cursor_.resume_at = cursor_.first < static_cast<int64_t>(plan_.points) ? plan_.point_action[cursor_.first]
                                                                         : plan_.actions.size();
  scheduler_->set_first_point(cursor_.first);
  try {
    prepare();
    // Bench time counts from here, as the plan's physical minimum does: the link's setup (the
    // sensor's rate and start, the gimbal's rate and watchdog: round trips, a few ms of wall time,
    // seconds of bench time at 1000x) is not the procedure's.
    clock_->count_bench_from_next_reading();
    io_->read_gimbal();
    events_.publish(RunStarted::of(session, cursor_.first, plan_));
    if (cursor_.resuming) log_.info("resuming at point {} of {}", cursor_.first + 1, plan_.points);
    for (size_t i = 0; i < plan_.actions.size(); ++i) {
      io_->check_abort();
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
  r.points_done = measurer_->next_point();
  if (const std::optional<double> bench_s = clock_->bench_s()) {
    const double bench = *bench_s;
    stats_.bench_s += bench;
    log_.info("bench time {:.2f} s (computation steps left out); the plan's physical minimum {:.2f} s, estimate {:.2f} s",
              bench, plan_.physical_s, plan_.estimated_s);
  }
  events_.publish(RunStopped{r.outcome, r.cause, r.reason, r.points_done, r.safe_state, {}});
  stats_.wall_s += seconds_since(t0);
  return r;
}

}  // namespace fpss
