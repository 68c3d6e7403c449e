#include "procedures/engine.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <cstring>
#include <ctime>
#include <limits>
#include <thread>

#include "procedures/align.h"

namespace fpss {

const char* to_string(RunOutcome o) {
  switch (o) {
    case RunOutcome::completed: return "completed";
    case RunOutcome::failed: return "failed";
    case RunOutcome::interrupted: return "interrupted";
  }
  return "?";
}

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Adds the time spent in a scope to a counter.
struct Timed {
  explicit Timed(double& acc) : acc_(acc), t0_(Clock::now()) {}
  ~Timed() { acc_ += seconds_since(t0_); }
  double& acc_;
  Clock::time_point t0_;
};

std::string fault_name(const GimbalState& st) {
  return st.fault != GimbalFault::none ? to_string(st.fault) : "fault bit set";
}

std::string deg(double arcsec) { return fmt::format("{:+.4f} deg", arcsec / 3600.0); }

std::string label(const Action& a) {
  return a.is_point() ? fmt::format("point {}", a.point + 1) : fmt::format("step {}", a.step_index);
}

// Failures of one measurement attempt, by the device that caused them, so recovery knows what to reset.
struct SensorFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};
struct GimbalFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace

Engine::Engine(Gimbal& gimbal, Sensor& sensor, const EngineSettings& bench, const Plan& plan, RunRecorder& recorder,
               spdlog::logger& log, RunControl& control, EngineHooks hooks)
    : g_(gimbal), s_(sensor), b_(bench), plan_(plan), rec_(recorder), log_(log), ctl_(control),
      hooks_(std::move(hooks)) {}

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
  log_.info("paused at the last point; the gimbal holds (send SIGUSR1 again to continue)");
  while (ctl_.pause.load()) {
    check_abort();
    read_gimbal();  // keeps the link (and a watchdog) alive
    Timed t(stats_.sleep_s);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  log_.info("continuing");
}

GimbalState Engine::move_and_wait(double pitch, double yaw, double timeout_physical_s, bool homing) {
  {
    Timed t(stats_.device_s);
    moved_ = true;
    if (homing) g_.home();
    else g_.move_to(pitch, yaw);
  }
  // Communication slack on top of the physical time: a slow link must not look like a stuck axis.
  const double timeout_wall = b_.wall(timeout_physical_s) + 2.0;
  const auto start = Clock::now();
  const double tol = b_.in_position_tolerance_arcsec;
  GimbalState st;
  for (;;) {
    check_abort();
    st = read_gimbal();
    if (st.has(kFault) || st.fault != GimbalFault::none) {
      throw GimbalFailure(fmt::format("gimbal fault ({}) while moving to pitch {}, yaw {}", fault_name(st),
                                      deg(pitch), deg(yaw)));
    }
    const bool there = homing ? st.has(kHomed)
                              : std::fabs(st.pitch_arcsec - pitch) <= tol && std::fabs(st.yaw_arcsec - yaw) <= tol;
    if (there && st.has(kInPosition) && !st.has(kMoving)) return st;
    if (seconds_since(start) > timeout_wall) {
      throw GimbalFailure(fmt::format("gimbal not in position at pitch {}, yaw {} within {:.1f} s (at pitch {}, yaw "
                                      "{}, status 0x{:02x})",
                                      deg(pitch), deg(yaw), timeout_wall, deg(st.pitch_arcsec), deg(st.yaw_arcsec),
                                      st.status));
    }
    Timed t(stats_.sleep_s);
    std::this_thread::sleep_for(std::chrono::duration<double>(b_.poll_interval_s));
  }
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
  time_base_ = last_time_ = rec_.last_time_s();
  if (!rec_.journal().empty()) {
    // A resume: the stand's time went on while the run was down (at the bench's pace).
    time_base_ += seconds_since_utc(rec_.journal().back().utc) * b_.time_scale;
  }
  GimbalState st = read_gimbal();
  Timed t(stats_.device_s);
  if (st.has(kFault) || st.fault != GimbalFault::none) {
    log_.warn("gimbal reports a fault ({}) at the start: clearing it", fault_name(st));
    g_.clear_fault();
  }
  g_.set_max_rate(b_.profile_rate_arcsec_s);
  g_.set_watchdog(b_.watchdog_s);
  s_.set_rate(static_cast<int>(std::lround(b_.sample_rate_hz)));
  s_.start();
}

void Engine::recover(const std::string& reason, bool sensor_side) {
  ++stats_.recoveries;
  // A short pause lets a dropped link come back (the drivers reconnect on the next request).
  sleep_physical(0);
  {
    Timed t(stats_.sleep_s);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  try {
    GimbalState st = read_gimbal();
    Timed t(stats_.device_s);
    if (st.has(kFault) || st.fault != GimbalFault::none) {
      log_.warn("clearing gimbal fault ({})", fault_name(st));
      g_.clear_fault();
    } else if (st.has(kMoving)) {
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

template <typename F>
void Engine::with_remeasure(const Action& a, F&& attempt_fn) {
  std::string reason;
  const int attempts = 1 + std::max(0, b_.max_remeasure);
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    bool sensor_side = false;
    try {
      attempt_fn(attempt);
      if (attempt > 1) log_.info("{} done on attempt {}", label(a), attempt);
      return;
    } catch (const SensorFailure& e) {
      reason = e.what();
      sensor_side = true;
    } catch (const GimbalFailure& e) {
      reason = e.what();
    } catch (const PointFailure& e) {
      reason = e.what();
    } catch (const LimitError&) {
      throw;  // refused before the wire: retrying cannot help
    } catch (const DeviceError& e) {
      reason = e.what();
      sensor_side = true;  // not knowing which device failed, reset both
    }
    log_.warn("{} attempt {}/{} not counted: {}", label(a), attempt, attempts, reason);
    check_abort();
    if (attempt < attempts) {
      ++stats_.remeasured;
      recover(reason, sensor_side);
    }
  }
  throw PointFailure(fmt::format("{} failed after {} attempts: {}",
                                 a.is_point() ? a.describe() : fmt::format("{} ({})", label(a), a.describe()), attempts,
                                 reason));
}

void Engine::measure_dwell(const Action& a, int session) {
  with_remeasure(a, [&](int attempt) {
    move_and_wait(a.pitch_arcsec, a.yaw_arcsec, b_.move_timeout_s);
    sleep_physical(a.settle_s);
    const double settled_host = host_now_s();
    GimbalState before;
    try {
      {
        Timed t(stats_.device_s);
        s_.flush();
      }
      before = read_gimbal();
    } catch (const DeviceError& e) {
      throw PointFailure(e.what());
    }
    auto check_still = [&](const GimbalState& st, const char* when) {
      if (st.has(kFault) || st.fault != GimbalFault::none) {
        throw GimbalFailure(fmt::format("gimbal fault ({}) {} sampling", fault_name(st), when));
      }
      const double tol = b_.in_position_tolerance_arcsec;
      if (st.has(kMoving) || std::fabs(st.pitch_arcsec - a.pitch_arcsec) > tol ||
          std::fabs(st.yaw_arcsec - a.yaw_arcsec) > tol) {
        throw GimbalFailure(fmt::format("gimbal left the point {} sampling (pitch {}, yaw {}, status 0x{:02x})", when,
                                        deg(st.pitch_arcsec), deg(st.yaw_arcsec), st.status));
      }
    };
    check_still(before, "before");
    const double frame_wait = b_.wall(1.0 / b_.sample_rate_hz) + b_.frame_timeout_s;
    std::vector<SensorSample> frames;
    std::vector<GimbalState> refs;
    frames.reserve(static_cast<size_t>(a.frames));
    refs.reserve(static_cast<size_t>(a.frames));
    int invalid = 0;
    uint8_t last_bad_status = 0;
    while (static_cast<int>(frames.size()) < a.frames) {
      check_abort();
      std::optional<SensorSample> f;
      try {
        Timed t(stats_.device_s);
        f = s_.next_sample(frame_wait);
      } catch (const DeviceError& e) {
        throw SensorFailure(e.what());
      }
      if (!f) throw SensorFailure(fmt::format("the sensor sent no frame within {:.2f} s", frame_wait));
      if (f->host_time_s < settled_host) continue;  // on its way before the settle ended
      // One clock for both devices: a frame stamped before the settled gimbal reading was taken
      // during the move, however late it arrives (a sensor stream catching up after a stall).
      if (b_.clock == ClockSync::shared && sensor_clock_s(*f) + 1e-6 < before.sample_time_us * 1e-6) continue;
      if (!f->valid()) {
        last_bad_status = f->status;
        if (++invalid > a.max_invalid) {
          throw SensorFailure(fmt::format("{} invalid frame(s) (status 0x{:02x}; {} tolerated)", invalid,
                                          last_bad_status, a.max_invalid));
        }
        continue;
      }
      frames.push_back(*f);
      // Each frame gets its own encoder reading: the dwell's reference is then the mean of as many
      // readings as frames, not of two (the encoders' noise dominates a dwell's error otherwise).
      try {
        refs.push_back(read_gimbal());
      } catch (const DeviceError& e) {
        throw GimbalFailure(e.what());
      }
      check_still(refs.back(), "while");
    }
    const double temp = read_temperature_c(a);
    std::vector<RecordedRow> rows;
    rows.reserve(frames.size());
    for (size_t i = 0; i < frames.size(); ++i) {
      const GimbalState& g = refs[i];
      const GimbalRef ref{static_cast<double>(g.sample_time_us) / 1e6, g.pitch_arcsec, g.yaw_arcsec, g.status};
      rows.push_back(make_row(a, a.phase, frames[i], sensor_clock_s(frames[i]), ref, temp, attempt, session));
    }
    {
      Timed t(stats_.storage_s);
      rec_.append_point(a.point, rows, attempt, session);
    }
    ++stats_.points;
    if (hooks_.point_done) hooks_.point_done(a, rows);
  });
}

void Engine::measure_slew(const Action& a, int session) {
  with_remeasure(a, [&](int attempt) {
    move_and_wait(a.start_pitch_arcsec, a.start_yaw_arcsec, b_.move_timeout_s);
    sleep_physical(a.settle_s);
    struct RateGuard {
      Engine& e;
      ~RateGuard() {
        try {
          Timed t(e.stats_.device_s);
          e.g_.set_max_rate(e.b_.profile_rate_arcsec_s);
        } catch (const DeviceError& ex) {
          e.log_.warn("could not restore the profile rate: {}", ex.what());
        }
      }
    };
    std::vector<GimbalFix> fixes;
    std::vector<SensorSample> frames;
    auto fix = [&](const GimbalState& st) {
      fixes.push_back(GimbalFix{static_cast<double>(st.sample_time_us) / 1e6, st.host_time_s, st.pitch_arcsec,
                                st.yaw_arcsec, st.pitch_rate_arcsec_s, st.yaw_rate_arcsec_s, st.status});
    };
    auto drain = [&] {
      Timed t(stats_.device_s);
      while (auto f = s_.next_sample(0.0)) frames.push_back(*f);
    };
    try {
      {
        Timed t(stats_.device_s);
        g_.set_max_rate(a.rate_arcsec_s);
      }
      RateGuard guard{*this};
      {
        Timed t(stats_.device_s);
        s_.flush();
      }
      fix(read_gimbal());
      {
        Timed t(stats_.device_s);
        g_.move_to(a.pitch_arcsec, a.yaw_arcsec);
      }
      const double span = std::fabs(a.axis == StandAxis::pitch ? a.pitch_arcsec - a.start_pitch_arcsec
                                                               : a.yaw_arcsec - a.start_yaw_arcsec);
      const double timeout_wall = b_.wall(span / a.rate_arcsec_s * 2 + b_.move_timeout_s) + 2.0;
      const auto start = Clock::now();
      const double tol = b_.in_position_tolerance_arcsec;
      for (;;) {
        check_abort();
        GimbalState st = read_gimbal();
        fix(st);
        if (st.has(kFault) || st.fault != GimbalFault::none) {
          throw GimbalFailure(fmt::format("gimbal fault ({}) during the slew", fault_name(st)));
        }
        drain();
        if (st.has(kInPosition) && !st.has(kMoving) && std::fabs(st.pitch_arcsec - a.pitch_arcsec) <= tol &&
            std::fabs(st.yaw_arcsec - a.yaw_arcsec) <= tol) {
          break;
        }
        if (seconds_since(start) > timeout_wall) {
          throw GimbalFailure(fmt::format("slew did not reach its end within {:.1f} s (at pitch {}, yaw {})",
                                          timeout_wall, deg(st.pitch_arcsec), deg(st.yaw_arcsec)));
        }
        Timed t(stats_.sleep_s);
        std::this_thread::sleep_for(std::chrono::microseconds(500));
      }
      // Frames sampled before the arrival may still be on the line: wait one frame period more.
      {
        const double frame_wait = b_.wall(2.0 / b_.sample_rate_hz) + 0.05;
        Timed t(stats_.device_s);
        if (auto f = s_.next_sample(frame_wait)) frames.push_back(*f);
      }
      drain();
    } catch (const DeviceError& e) {
      throw PointFailure(e.what());
    }
    if (frames.empty()) throw SensorFailure("the sensor sent no frame during the slew");

    // Sensor time -> gimbal time.
    std::vector<double> g_times(frames.size());
    std::vector<double> s_times(frames.size());
    if (b_.clock == ClockSync::shared) {
      for (size_t i = 0; i < frames.size(); ++i) {
        // Unwrap against the gimbal time nearest in host time (both on one clock).
        auto it = std::lower_bound(fixes.begin(), fixes.end(), frames[i].host_time_s,
                                   [](const GimbalFix& f, double h) { return f.host_time_s < h; });
        const double ref = (it == fixes.end() ? fixes.back() : *it).gimbal_time_s;
        s_times[i] = std::round((unwrap_near(frames[i].sensor_time_us, ref) + b_.sensor_time_offset_s) * 1e6) / 1e6;
        g_times[i] = s_times[i];
      }
    } else {
      std::vector<double> hs, ds, hg, dg;
      for (const auto& f : frames) {
        hs.push_back(f.host_time_s);
        ds.push_back(f.sensor_time_s);
      }
      for (const auto& f : fixes) {
        hg.push_back(f.host_time_s);
        dg.push_back(f.gimbal_time_s);
      }
      const double cs = clock_offset(hs, ds, b_.time_scale), cg = clock_offset(hg, dg, b_.time_scale);
      for (size_t i = 0; i < frames.size(); ++i) {
        s_times[i] = frames[i].sensor_time_s + b_.sensor_time_offset_s;
        g_times[i] = s_times[i] + cs - cg;
      }
    }
    const double temp = read_temperature_c(a);
    std::vector<RecordedRow> rows;
    int invalid = 0, gapped = 0;
    double next_keep = -std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < frames.size(); ++i) {
      const auto& f = frames[i];
      auto at = interpolate_at(fixes, g_times[i]);
      if (!at) continue;  // before the first or after the last gimbal reading: no reference
      if (at->gap_s > b_.max_reference_gap_s) {
        ++gapped;  // the gimbal was not read often enough around this frame to trust its reference
        continue;
      }
      if (!f.valid()) {
        ++invalid;
        continue;
      }
      // One sample per period on the sensor's clock: the first frame at least a period after the
      // last one kept (a microsecond of slack for float rounding).
      if (s_times[i] + 1e-6 < next_keep) continue;
      next_keep = s_times[i] + a.sample_period_s;
      const GimbalRef ref{g_times[i], at->pitch_arcsec, at->yaw_arcsec, at->status};
      rows.push_back(make_row(a, Phase::slew, f, s_times[i], ref, temp, attempt, session));
    }
    if (rows.empty()) {
      throw SensorFailure(fmt::format("no valid frame aligned with the gimbal during the slew ({} frames, {} invalid)",
                                      frames.size(), invalid));
    }
    if (invalid > 0) log_.warn("point {}: {} invalid frame(s) during the slew skipped", a.point + 1, invalid);
    if (gapped > 0) {
      log_.info("point {}: {} frame(s) skipped: gimbal readings around them more than {} s apart", a.point + 1, gapped,
                b_.max_reference_gap_s);
    }
    double max_gap = 0;
    for (size_t i = 1; i < fixes.size(); ++i) max_gap = std::max(max_gap, fixes[i].gimbal_time_s - fixes[i - 1].gimbal_time_s);
    log_.debug("point {}: slew of {} frames, {} kept, {} gimbal readings (largest gap {:.1f} ms of bench time)",
               a.point + 1, frames.size(), rows.size(), fixes.size(), max_gap * 1e3);
    {
      Timed t(stats_.storage_s);
      rec_.append_point(a.point, rows, attempt, session);
    }
    ++stats_.points;
    if (hooks_.point_done) hooks_.point_done(a, rows);
  });
}

void Engine::do_home(const Action& a) {
  const double timeout = a.timeout_s > 0 ? a.timeout_s : b_.home_timeout_s;
  with_remeasure(a, [&](int) { move_and_wait(0, 0, timeout, true); });
}

void Engine::do_move(const Action& a) {
  auto go = [&](int) {
    if (a.rate_arcsec_s > 0) {
      Timed t(stats_.device_s);
      g_.set_max_rate(a.rate_arcsec_s);
    }
    try {
      move_and_wait(a.pitch_arcsec, a.yaw_arcsec, b_.move_timeout_s);
    } catch (...) {
      if (a.rate_arcsec_s > 0) {
        try {
          g_.set_max_rate(b_.profile_rate_arcsec_s);
        } catch (const DeviceError&) {
        }
      }
      throw;
    }
    if (a.rate_arcsec_s > 0) {
      Timed t(stats_.device_s);
      g_.set_max_rate(b_.profile_rate_arcsec_s);
    }
  };
  with_remeasure(a, go);
}

bool Engine::safe_stop() {
  stopping_ = true;
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
          g_.set_max_rate(b_.profile_rate_arcsec_s);
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

EngineResult Engine::run(int session) {
  const auto t0 = Clock::now();
  EngineResult r;
  const int64_t first = rec_.next_point();
  const bool resuming = first > 0;
  // Actions before the first point still to measure were done in an earlier session (except
  // calibrate and check, which are computations and run again on the same data).
  const size_t resume_at = first < static_cast<int64_t>(plan_.points) ? plan_.point_action[first]
                                                                      : plan_.actions.size();
  try {
    prepare();
    if (resuming) log_.info("resuming at point {} of {}", first + 1, plan_.points);
    bool homed_again = false;
    for (size_t i = 0; i < plan_.actions.size(); ++i) {
      const Action& a = plan_.actions[i];
      check_abort();
      wait_while_paused();
      const bool done_before = resuming && i < resume_at;
      switch (a.kind) {
        case Action::Kind::home:
          if (done_before) {
            // After a restart the axes may need homing again; once is enough.
            if (!homed_again && resume_at < plan_.actions.size()) {
              do_home(a);
              homed_again = true;
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
          sleep_physical(a.settle_s);
          break;
        case Action::Kind::dwell:
          if (a.point < first) break;
          log_.debug("step {}: {}", a.step_index, a.describe());
          measure_dwell(a, session);
          break;
        case Action::Kind::slew:
          if (a.point < first) break;
          log_.info("step {}: {}", a.step_index, a.describe());
          measure_slew(a, session);
          break;
        case Action::Kind::calibrate:
          log_.info("step {}: calibrate", a.step_index);
          if (hooks_.calibrate) {
            Timed t(stats_.calibrate_s);
            hooks_.calibrate(a);
          }
          break;
        case Action::Kind::check: {
          log_.info("step {}: check", a.step_index);
          const std::string broken = hooks_.check ? hooks_.check(a) : std::string();
          if (!broken.empty()) throw PointFailure(fmt::format("step {} (check): {}", a.step_index, broken));
          break;
        }
      }
    }
    r.outcome = RunOutcome::completed;
  } catch (const Aborted&) {
    r.outcome = RunOutcome::interrupted;
    const int sig = ctl_.signal.load();
    r.reason = sig ? fmt::format("interrupted by signal {} ({})", sig, strsignal(sig)) : "interrupted";
  } catch (const std::exception& e) {
    r.outcome = RunOutcome::failed;
    r.reason = e.what();
  }
  if (r.outcome != RunOutcome::completed) log_.error("run {}: {}", to_string(r.outcome), r.reason);
  r.safe_state = safe_stop();
  if (!r.safe_state) {
    log_.error("the gimbal could not be returned to null: check the stand");
    if (r.outcome == RunOutcome::completed) {
      r.outcome = RunOutcome::failed;
      r.reason = "the gimbal could not be returned to null at the end";
    }
  }
  r.points_done = rec_.next_point();
  stats_.wall_s += seconds_since(t0);
  return r;
}

}  // namespace fpss
