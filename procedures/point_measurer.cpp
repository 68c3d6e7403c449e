#include "procedures/point_measurer.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>
#include <utility>

#include "procedures/align.h"
#include "procedures/engine_detail.h"

namespace fpss {

using namespace engine_detail;

PointMeasurer::PointMeasurer(EngineIo& io, EngineClock& clock, MoveScheduler& scheduler, int64_t next_point)
    : io_(io), clock_(clock), sched_(scheduler), b_(io.settings()), events_(io.events()), log_(io.log()),
      stats_(io.stats()), next_point_(next_point) {}

namespace {
// At rest in position at a target (pitch, yaw) within tol.
bool in_position_at(const GimbalState& st, std::pair<double, double> target, double tol) {
  return st.has(kInPosition) && !st.has(kMoving) && std::fabs(st.pitch_arcsec - target.first) <= tol &&
         std::fabs(st.yaw_arcsec - target.second) <= tol;
}
}  // namespace

void PointMeasurer::publish_point(const Action& a, std::vector<RecordedRow> measured, int attempt, int session,
                                  int invalid) {
  // One copy of the rows, shared by both events and whoever keeps them.
  const SharedRows rows = std::make_shared<const std::vector<RecordedRow>>(std::move(measured));
  const EventPoint point = EventPoint::of(a);
  try {
    Timed t(stats_.storage_s);
    events_.publish(Samples{point, rows, rows->size(), attempt, session, {}});
  } catch (const std::exception& e) {
    throw StorageFailure(e.what());
  }
  next_point_ = a.point + 1;
  ++stats_.points;
  PointDone done{.point = point, .rows = rows, .stats = PointStats::of(*rows), .attempts = attempt, .invalid_frames = invalid};
  if (!rows->empty()) done.temperature_c = rows->front().temperature_c;
  events_.publish(done);
}

RecordedRow PointMeasurer::make_row(const Action& a, Phase phase, const SensorSample& f, double sensor_time_s,
                                    double stand_time_s, const GimbalRef& g, double temperature_c, int attempt,
                                    int session, const EngineUnit& u) {
  // The reference angles are the true ones when the reference's calibration is known; the raw
  // encoder readings stay in the row's provenance.
  const auto [true_p, true_y] =
      b_.reference ? b_.reference->true_from_reading(g.pitch_arcsec, g.yaw_arcsec) : std::pair{g.pitch_arcsec, g.yaw_arcsec};
  const auto [ref_a, ref_b] = u.axes.sensor_from_stand(true_p, true_y);
  RecordedRow r;
  r.unit = u.id;
  r.sensor_time_s = sensor_time_s;
  r.sample = Sample{stand_time_s, phase, a.point + 1, ref_a, ref_b,
                    static_cast<double>(f.counts_alpha), static_cast<double>(f.counts_beta)};
  r.frame_seq = f.seq;
  r.sensor_status = f.status;
  r.host_time_s = clock_.session_host_s(f.host_time_s);
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

void PointMeasurer::set_approach(RecordedRow& row, const AxisMapping& axes) const {
  // The stand axes' sides through the unit's mapping: a sign per sensor axis (the mapping only
  // swaps and negates axes).
  const auto [p, y] = sched_.approach();
  const auto [a, b] = axes.sensor_from_stand(p, y);
  row.approach_pitch = a;
  row.approach_yaw = b;
}

double PointMeasurer::since_arrival_s(const SensorSample& f, const GimbalState& arrived, double arrived_s) const {
  // One clock for both devices: the frame's own stamp. Else the host's receipts of the frame and
  // of the in-position reading, at the bench's pace, from that reading's stamp back to the arrival.
  const double t = b_.clock == ClockSync::shared
                       ? clock_.sensor_clock_s(f) - arrived_s
                       : (f.host_time_s - arrived.host_time_s) * b_.time_scale +
                             (static_cast<double>(arrived.sample_time_us) * 1e-6 - arrived_s);
  return std::round(t * 1e6) / 1e6;  // whole microseconds, as the devices count
}

void PointMeasurer::recover(const std::string& reason, bool sensor_side) {
  ++stats_.recoveries;
  sched_.drop_moves_ahead();  // the gimbal is stopped below: a move commanded ahead is void
  // A short pause lets a dropped link come back (the drivers reconnect on the next request).
  sched_.sleep_physical(0);
  {
    Timed t(stats_.sleep_s);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  try {
    GimbalState st = io_.read_gimbal();
    Timed t(stats_.device_s);
    // Whoever changed them, the stand's settings are written back.
    if (io_.commanded().max_rate_arcsec_s > 0) io_.command_rate(io_.commanded().max_rate_arcsec_s);
    io_.command_watchdog(io_.commanded().watchdog_s);
    if (st.has(kFault) || st.fault != GimbalFault::none) {
      io_.warn(nullptr, fmt::format("clearing gimbal fault ({})", fault_name(st)));
      io_.gimbal().clear_fault();
    } else if (st.has(kMoving) || st.has(kMovePending)) {
      io_.gimbal().stop();
    }
    io_.note_place(st.pitch_arcsec, st.yaw_arcsec);  // stopped about here: the next move starts there
  } catch (const DeviceError& e) {
    log_.warn("gimbal not answering while recovering: {}", e.what());
  }
  if (sensor_side) {
    try {
      Timed t(stats_.device_s);
      log_.warn("restarting the sensor stream");
      io_.sensor().stop();
      io_.sensor().flush();
      io_.sensor().start();
    } catch (const DeviceError& e) {
      log_.warn("sensor not answering while recovering: {}", e.what());
    }
  }
}

void PointMeasurer::with_remeasure(const Action& a, const std::function<void(int)>& attempt_fn) {
  // Several units: a lead that fails the point on every attempt is dropped, and the next unit
  // measures the point afresh (its attempts counted anew).
  for (;;) {
    const size_t lead = io_.lead_index();
    const uint64_t crc0 = crc_errors(lead);
    try {
      attempts(a, attempt_fn);
      return;
    } catch (const PointFailure& e) {
      if (!e.sensor_side || !a.is_point() || !io_.can_lose_lead()) throw;
      const LossCause cause = loss_cause(lead, crc_errors(lead) - crc0, a, e.cause == StopCause::sensor_invalid);
      io_.lose(lead, cause, e.what(), a.point);
      flush_followers();
    }
  }
}

void PointMeasurer::attempts(const Action& a, const std::function<void(int)>& attempt_fn) {
  std::string reason;
  StopCause cause = StopCause::other;
  const int attempts = 1 + std::max(0, b_.max_remeasure);
  bool last_sensor_side = false;
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    bool sensor_side = false;
    try {
      if (a.is_point()) events_.publish(PointStarted{EventPoint::of(a), attempt, {}});
      attempt_fn(attempt);
      if (attempt > 1) log_.info("{} done on attempt {}", label(a), attempt);
      return;
    } catch (const SensorFailure& e) {
      reason = e.what();
      cause = e.cause;
      sensor_side = true;
    } catch (const GimbalFailure& e) {
      if (e.final) throw PointFailure(fmt::format("{}: {}", a.is_point() ? a.describe() : label(a), e.what()), e.cause);
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
    last_sensor_side = sensor_side;
    io_.warn(&a, fmt::format("{} attempt {}/{} not counted: {}", label(a), attempt, attempts, reason));
    io_.check_abort();
    if (attempt < attempts) {
      ++stats_.remeasured;
      recover(reason, sensor_side);
    }
  }
  PointFailure failure(fmt::format("{} failed after {} attempts: {}",
                                   a.is_point() ? a.describe() : fmt::format("{} ({})", label(a), a.describe()), attempts,
                                   reason),
                       cause);
  failure.sensor_side = last_sensor_side;
  throw failure;
}

std::optional<SensorSample> PointMeasurer::settle(const Action& a, const GimbalState& arrived, double& settled_host_s) {
  // The settle counts from the gimbal's arrival. One clock for both devices: the frames say when
  // it is over, and the first frame after it is the dwell's first; else the host clock says, and
  // a reading after it starts the dwell.
  std::optional<SensorSample> first = sched_.wait_bench_until(sched_.arrived_s() + a.settle_s);
  settled_host_s = clock_.host_now_s();
  if (!first && b_.clock != ClockSync::shared) {
    try {
      {
        Timed t(stats_.device_s);
        io_.sensor().flush();
      }
      io_.check_still(a, io_.read_gimbal(), "before");
    } catch (const DeviceError& e) {
      throw PointFailure(e.what());
    }
  } else {
    io_.check_still(a, arrived, "before");
  }
  return first;
}

std::optional<SensorSample> PointMeasurer::next_dwell_frame(std::optional<SensorSample>& first) {
  if (first) return std::exchange(first, std::nullopt);
  try {
    Timed t(stats_.device_s);
    return io_.sensor().next_sample(b_.wall(1.0 / b_.sample_rate_hz) + b_.frame_timeout_s);
  } catch (const DeviceError& e) {
    throw SensorFailure(e.what());
  }
}

PointMeasurer::DwellFrames PointMeasurer::take_dwell(const Action& a, const GimbalState& arrived) {
  const bool shared = b_.clock == ClockSync::shared;
  double settled_host = 0;
  const double settled_bench = sched_.arrived_s() + a.settle_s;
  const double period_s = 1.0 / b_.sample_rate_hz;
  const bool link_slower_than_frames = b_.link_round_trip_s * b_.time_scale > period_s;
  DwellFrames d;
  d.frames.reserve(static_cast<size_t>(a.frames));
  // The next move's start, scheduled on the gimbal's clock for half a frame period after the
  // dwell's last frame, so no round trip of the host's lies between two dwells however late the
  // host is (docs/procedures.md, "How the engine waits"): before the settle when the frame grid
  // says where the dwell's frames fall, else at its first frame.
  // With the move queued while the gimbal came here, that one (queue_move_after_next).
  std::optional<double> move_at_s;
  if (shared && clock_.frame_grid_known()) {
    const double end_s = clock_.dwell_end_s(a, clock_.first_frame_from(settled_bench));
    move_at_s = sched_.has_queued() ? sched_.adopt_queued_move(a, end_s, arrived) : sched_.schedule_next_move(a, end_s);
  }
  std::optional<SensorSample> first = settle(a, arrived, settled_host);
  d.settled_bench_s = settled_bench;
  d.settled_host_s = settled_host;
  bool reading = true;  // readings after the next move's start are no reference of this dwell
  uint8_t last_bad_status = 0;
  while (static_cast<int>(d.frames.size()) < a.frames) {
    io_.check_abort();
    std::optional<SensorSample> f = next_dwell_frame(first);
    if (!f) throw SensorFailure(fmt::format("the sensor sent no frame within {:.2f} s", b_.wall(period_s) + b_.frame_timeout_s));
    // One clock for both devices: a frame stamped before the settle ended was taken during
    // it, however late it arrives (a sensor stream catching up after a stall).
    if (shared && clock_.sensor_clock_s(*f) + 1e-6 < settled_bench) continue;
    // Host clocks: taken before the settle ended, however late it came (EngineClock::taken_host_s).
    if (!shared) {
      clock_.note_sensor_frame(*f);
      if (clock_.taken_host_s(*f) < settled_host) continue;
    }
    if (move_at_s && clock_.sensor_clock_s(*f) + 1e-6 >= *move_at_s) {
      throw PointFailure("a frame came after the next move's scheduled start (frames missing from the stream)");
    }
    if (!f->valid()) {
      last_bad_status = f->status;
      if (++d.invalid > a.max_invalid) {
        throw SensorFailure(fmt::format("{} invalid frame(s) (status 0x{:02x}; {} tolerated)", d.invalid,
                                        last_bad_status, a.max_invalid),
                            StopCause::sensor_invalid);
      }
      // One frame more (before the first valid frame, that frame puts the end where it belongs).
      if (move_at_s && !d.frames.empty()) sched_.reschedule_next_move(a, *move_at_s, *move_at_s + period_s);
      continue;
    }
    d.frames.push_back(*f);
    if (shared) clock_.note_frame(clock_.sensor_clock_s(*f));
    if (d.frames.size() == 1 && shared) {
      const double end_s = clock_.dwell_end_s(a, clock_.sensor_clock_s(*f));
      if (!move_at_s) move_at_s = sched_.schedule_next_move(a, end_s);
      else if (end_s > *move_at_s + 1e-6) sched_.reschedule_next_move(a, *move_at_s, end_s);  // frames missing
    }
    const bool last = static_cast<int>(d.frames.size()) == a.frames;
    // Each frame is referenced to the first encoder reading after it: the gimbal is read after
    // every frame (the dwell's reference is then the mean of as many readings as frames, not of
    // two: the encoders' noise dominates a dwell's error otherwise), unless the stand's link
    // takes longer than a frame period at its speed-up (an emulator at 1000x): then after each
    // run of frames that came during a reading, so the readings never hold the dwell back. With
    // the next move scheduled, the frames after the last reading before its start take that one.
    if (!reading || (last && move_at_s)) continue;
    if (link_slower_than_frames && !last) {
      try {
        Timed t(stats_.device_s);
        first = io_.sensor().next_sample(0.0);
      } catch (const DeviceError& e) {
        throw SensorFailure(e.what());
      }
      if (first) continue;
    }
    GimbalState st;
    try {
      st = io_.read_gimbal();
    } catch (const DeviceError& e) {
      throw GimbalFailure(e.what());
    }
    if (move_at_s && clock_.last_gimbal_s() + 1e-6 >= *move_at_s) {
      reading = false;  // the move has begun: no reference, no stillness to check
      continue;
    }
    io_.check_still(a, st, "while");
    d.refs.push_back(st);
    d.ref_of.resize(d.frames.size(), d.refs.size() - 1);
  }
  // A host so late that the gimbal had left before it could read it during the dwell: the frames
  // take the reading that found it there (at rest at the point, one reading for all), and the next
  // move waits for this dwell's end, so the gimbal stays put until the host has read it.
  sched_.set_late_for_schedule(move_at_s && d.refs.empty());
  if (d.refs.empty()) d.refs.push_back(arrived);
  d.ref_of.resize(d.frames.size(), d.refs.size() - 1);
  return d;
}

void PointMeasurer::measure_dwell(const Action& a, int session) {
  with_remeasure(a, [&](int attempt) {
    const GimbalState arrived = sched_.move_and_wait(a.pitch_arcsec, a.yaw_arcsec, b_.move_timeout_s);
    const double arrived_s = sched_.arrived_s();  // the gimbal's clock
    const DwellFrames d = take_dwell(a, arrived);
    // Everything the gimbal had to do here is done: its next move starts now (unless scheduled
    // already), and the checks and the storing below overlap it.
    sched_.command_next_move();
    sched_.queue_move_after_next();
    io_.verify_command();
    const double temp = io_.read_temperature_c(a);
    std::vector<RecordedRow> rows;
    rows.reserve(d.frames.size());
    for (size_t i = 0; i < d.frames.size(); ++i) {
      const GimbalState& g = d.refs[d.ref_of[i]];
      const GimbalRef ref{static_cast<double>(g.sample_time_us) / 1e6, g.pitch_arcsec, g.yaw_arcsec, g.status};
      const double ts = clock_.sensor_clock_s(d.frames[i]);
      rows.push_back(make_row(a, a.phase, d.frames[i], ts, clock_.stand_time(ts), ref, temp, attempt, session, io_.lead()));
      rows.back().time_since_move_s = since_arrival_s(d.frames[i], arrived, arrived_s);
      set_approach(rows.back(), io_.lead().axes);
    }
    for (size_t u : io_.followers()) {
      std::vector<RecordedRow> more = follower_dwell(a, u, d, rows, arrived, arrived_s, attempt, session);
      rows.insert(rows.end(), std::make_move_iterator(more.begin()), std::make_move_iterator(more.end()));
    }
    publish_point(a, std::move(rows), attempt, session, d.invalid);
  });
}

void PointMeasurer::slew_times(const std::vector<SensorSample>& frames, const std::vector<GimbalFix>& fixes,
                               std::vector<double>& s_times, std::vector<double>& g_times) const {
  g_times.assign(frames.size(), 0.0);
  s_times.assign(frames.size(), 0.0);
  if (b_.clock == ClockSync::shared) {
    for (size_t i = 0; i < frames.size(); ++i) {
      // Unwrap against the gimbal time nearest in host time (both on one clock).
      auto it = std::lower_bound(fixes.begin(), fixes.end(), frames[i].host_time_s,
                                 [](const GimbalFix& f, double h) { return f.host_time_s < h; });
      const double ref = (it == fixes.end() ? fixes.back() : *it).gimbal_time_s;
      s_times[i] = std::round((unwrap_near(frames[i].sensor_time_us, ref) + clock_.sensor_offset_s()) * 1e6) / 1e6;
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
      s_times[i] = frames[i].sensor_time_s + clock_.sensor_offset_s();
      g_times[i] = s_times[i] + cs - cg;
    }
  }
}

void PointMeasurer::measure_slew(const Action& a, int session) {
  with_remeasure(a, [&](int attempt) {
    sched_.move_and_wait(a.start_pitch_arcsec, a.start_yaw_arcsec, b_.move_timeout_s);
    sched_.wait_bench_until(sched_.arrived_s() + a.settle_s);
    struct RateGuard {
      PointMeasurer& e;
      ~RateGuard() {
        try {
          Timed t(e.stats_.device_s);
          e.io_.command_rate(e.b_.profile_rate_arcsec_s);
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
    auto drain = [&] {  // true when a frame came
      Timed t(stats_.device_s);
      const size_t n = frames.size();
      while (auto f = io_.sensor().next_sample(0.0)) frames.push_back(*f);
      return frames.size() > n;
    };
    try {
      RateGuard guard{*this};  // restores the profile rate however this ends
      {
        Timed t(stats_.device_s);
        io_.command_rate(a.rate_arcsec_s);
        io_.sensor().flush();
      }
      flush_followers();
      fix(io_.read_gimbal());
      {
        Timed t(stats_.device_s);
        io_.command_move(a.pitch_arcsec, a.yaw_arcsec);
      }
      const double leg_s = a.slew_span_arcsec() / a.rate_arcsec_s * 2 + b_.move_timeout_s;
      const double timeout_wall = b_.wall(leg_s * (a.reversals + 1)) + 2.0;
      const auto start = Clock::now();
      const double tol = b_.in_position_tolerance_arcsec;
      const double reading_wait = b_.wall(0.25 / b_.sample_rate_hz);  // frames between close readings
      for (int leg = 0;;) {  // legs: Action::leg_target, each from the instant the last is in position
        io_.check_abort();
        GimbalState st = io_.read_gimbal();
        fix(st);
        if (st.has(kFault) || st.fault != GimbalFault::none)
          throw GimbalFailure(fmt::format("gimbal fault ({}) during the slew", fault_name(st)));
        io_.check_commanded_place(st);
        if (in_position_at(st, a.leg_target(leg), tol)) {
          const auto from = leg > 0 ? a.leg_target(leg - 1) : std::pair{a.start_pitch_arcsec, a.start_yaw_arcsec};
          sched_.note_motion(from.first, from.second, st.pitch_arcsec, st.yaw_arcsec);
          if (leg++ == a.reversals) break;
          Timed t(stats_.device_s);
          io_.command_move(a.leg_target(leg).first, a.leg_target(leg).second);
        }
        if (seconds_since(start) > timeout_wall) {
          throw GimbalFailure(fmt::format("slew did not reach its end within {:.1f} s (at pitch {}, yaw {})",
                                          timeout_wall, deg(st.pitch_arcsec), deg(st.yaw_arcsec)));
        }
        // No frame since the last reading: the next is waited for, a quarter frame period at most.
        if (!drain()) {
          Timed t(stats_.device_s);
          if (auto f = io_.sensor().next_sample(reading_wait)) frames.push_back(*f);
        }
      }
      // Frames sampled before the arrival may still be on the line: wait one frame period more.
      {
        const double frame_wait = b_.wall(2.0 / b_.sample_rate_hz) + 0.05;
        Timed t(stats_.device_s);
        if (auto f = io_.sensor().next_sample(frame_wait)) frames.push_back(*f);
      }
      drain();
    } catch (const DeviceError& e) {
      throw PointFailure(e.what());
    }
    io_.verify_command();
    if (frames.empty()) throw SensorFailure("the sensor sent no frame during the slew");
    int invalid = 0, gapped = 0;
    std::vector<RecordedRow> rows = slew_rows(a, io_.lead(), true, frames, fixes, attempt, session, invalid, gapped);
    if (rows.empty()) {
      throw SensorFailure(fmt::format("no valid frame aligned with the gimbal during the slew ({} frames, {} invalid)",
                                      frames.size(), invalid),
                          invalid > 0 ? StopCause::sensor_invalid : StopCause::sensor_timeout);
    }
    if (invalid > 0) io_.warn(&a, fmt::format("point {}: {} invalid frame(s) during the slew skipped", a.point + 1, invalid));
    if (gapped > 0) {
      log_.info("point {}: {} frame(s) skipped: gimbal readings around them more than {} s apart", a.point + 1, gapped,
                b_.max_reference_gap_s);
    }
    const std::vector<std::vector<SensorSample>> more = drain_followers();
    const std::vector<size_t> followers = io_.followers();
    for (size_t k = 0; k < followers.size(); ++k) {
      int f_invalid = 0, f_gapped = 0;
      std::vector<RecordedRow> f_rows =
          slew_rows(a, io_.unit(followers[k]), false, more[k], fixes, attempt, session, f_invalid, f_gapped);
      if (f_rows.empty()) {
        follower_failed(a, followers[k], fmt::format("no valid frame aligned with the gimbal during the slew ({} frames, "
                                                     "{} invalid)", more[k].size(), f_invalid), f_invalid);
        continue;
      }
      follower_ok(followers[k]);
      rows.insert(rows.end(), std::make_move_iterator(f_rows.begin()), std::make_move_iterator(f_rows.end()));
    }
    double max_gap = 0;
    for (size_t i = 1; i < fixes.size(); ++i) max_gap = std::max(max_gap, fixes[i].gimbal_time_s - fixes[i - 1].gimbal_time_s);
    log_.debug("point {}: slew of {} frames, {} kept, {} gimbal readings (largest gap {:.1f} ms of bench time)",
               a.point + 1, frames.size(), rows.size(), fixes.size(), max_gap * 1e3);
    publish_point(a, std::move(rows), attempt, session, invalid);
  });
}

std::vector<RecordedRow> PointMeasurer::slew_rows(const Action& a, const EngineUnit& u, bool lead,
                                                  const std::vector<SensorSample>& frames,
                                                  const std::vector<GimbalFix>& fixes, int attempt, int session,
                                                  int& invalid, int& gapped) {
  std::vector<RecordedRow> rows;
  if (frames.empty()) return rows;
  std::vector<double> s_times, g_times;  // sensor time -> gimbal time
  slew_times(frames, fixes, s_times, g_times);
  const double temp = lead ? io_.read_temperature_c(a) : io_.read_temperature_c(a, *u.sensor);
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
    // A follower's frames are on the lead's stand time through the shared clock, else through the
    // gimbal's clock (g_times: the same instant on the gimbal's clock for every unit).
    const double stand_s = lead ? clock_.stand_time(s_times[i])
                                : clock_.stand_time_of(b_.clock == ClockSync::shared ? s_times[i] : g_times[i]);
    rows.push_back(make_row(a, Phase::slew, f, s_times[i], stand_s, ref, temp, attempt, session, u));
  }
  return rows;
}

}  // namespace fpss
