// The engine's other units on a point: their frames taken over the lead's dwell or slew, and a unit that fails dropped.
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>

#include "procedures/engine_detail.h"
#include "procedures/point_measurer.h"

namespace fpss {

using namespace engine_detail;

void PointMeasurer::flush_followers() {
  for (size_t u : io_.followers()) {
    try {
      Timed t(stats_.device_s);
      io_.unit(u).sensor->flush();
    } catch (const DeviceError& e) {
      log_.warn("unit {}: flush failed: {}", io_.unit_name(u), e.what());
    }
  }
}

std::vector<std::vector<SensorSample>> PointMeasurer::drain_followers() {
  std::vector<std::vector<SensorSample>> out;
  for (size_t u : io_.followers()) {
    out.emplace_back();
    try {
      Timed t(stats_.device_s);
      while (auto f = io_.unit(u).sensor->next_sample(0.0)) out.back().push_back(*f);
    } catch (const DeviceError& e) {
      log_.warn("unit {}: {}", io_.unit_name(u), e.what());
    }
  }
  return out;
}

std::vector<RecordedRow> PointMeasurer::follower_dwell(const Action& a, size_t ui, const DwellFrames& d,
                                                       const std::vector<RecordedRow>& lead_rows,
                                                       const GimbalState& arrived, double arrived_s, int attempt,
                                                       int session) {
  const EngineUnit& u = io_.unit(ui);
  const bool shared = b_.clock == ClockSync::shared;
  // Its own rate, timeout and clock offset; the dwell's window is the lead's.
  const double period_s = 1.0 / io_.rate_hz(ui), offset_s = io_.sensor_offset_s(ui);
  const double lead_period_s = 1.0 / b_.sample_rate_hz;
  // One clock for every device: the frames' stamps say when they were sampled; else when they were
  // taken on the host's clock, from each sensor's own stamps and link (FrameTakenClock).
  while (follower_taken_.size() <= ui) follower_taken_.emplace_back(b_.time_scale);
  FrameTakenClock& taken = follower_taken_[ui];
  auto when = [&](const SensorSample& f) { return shared ? clock_.sensor_clock_s(f, offset_s) : taken.taken_host_s(f); };
  auto lead_when = [&](const SensorSample& f) { return shared ? clock_.sensor_clock_s(f) : clock_.taken_host_s(f); };
  const double lo = shared ? d.settled_bench_s : d.settled_host_s;
  const double hi = lead_when(d.frames.back()) + (shared ? 0.5 * lead_period_s : b_.wall(0.5 * lead_period_s));
  // As many frames as its rate puts in the lead's dwell (the lead's count at the lead's rate).
  const int wanted = std::max(1, static_cast<int>(std::lround(a.frames * lead_period_s / period_s)));
  std::vector<SensorSample> frames;
  int invalid = 0;
  std::string failure;
  const auto deadline = Clock::now() + std::chrono::duration<double>(b_.wall(period_s) + io_.frame_timeout_s(ui));
  while (static_cast<int>(frames.size()) < wanted) {
    const double left = std::chrono::duration<double>(deadline - Clock::now()).count();
    if (left <= 0) break;
    std::optional<SensorSample> f;
    try {
      Timed t(stats_.device_s);
      f = u.sensor->next_sample(left);
    } catch (const DeviceError& e) {
      failure = e.what();
      break;
    }
    if (!f) break;
    if (!shared) taken.note(*f);
    const double t = when(*f);
    if (t + 1e-6 < lo) continue;  // sampled before the settle ended (during the move)
    if (t > hi + 1e-6) break;     // after the dwell: the next move's
    if (!f->valid()) {
      ++invalid;
      continue;
    }
    frames.push_back(*f);
  }
  if (frames.empty()) {
    follower_failed(a, ui, failure.empty() ? fmt::format("no valid frame over the dwell ({} invalid)", invalid) : failure,
                    invalid);
    return {};
  }
  follower_ok(ui);
  const double temp = io_.read_temperature_c(a, *u.sensor);
  std::vector<double> lead_t;
  for (const auto& f : d.frames) lead_t.push_back(lead_when(f));
  std::vector<RecordedRow> rows;
  for (const auto& f : frames) {
    // The lead frame nearest in time gives the gimbal reading (and, off a shared clock, the time).
    const double t = when(f);
    size_t j = static_cast<size_t>(std::lower_bound(lead_t.begin(), lead_t.end(), t) - lead_t.begin());
    if (j == lead_t.size() || (j > 0 && t - lead_t[j - 1] < lead_t[j] - t)) j = j == 0 ? 0 : j - 1;
    const GimbalState& g = d.refs[d.ref_of[j]];
    const GimbalRef ref{static_cast<double>(g.sample_time_us) / 1e6, g.pitch_arcsec, g.yaw_arcsec, g.status};
    const double ts = shared ? clock_.sensor_clock_s(f, offset_s) : f.sensor_time_s + offset_s;
    const double stand_s = shared ? clock_.stand_time_of(ts)
                                  : std::round((lead_rows[j].sample.time_s + (t - lead_t[j]) * b_.time_scale) * 1e6) / 1e6;
    rows.push_back(make_row(a, a.phase, f, ts, stand_s, ref, temp, attempt, session, u));
    rows.back().time_since_move_s = since_arrival_s(f, arrived, arrived_s);
    set_approach(rows.back(), u.axes);
  }
  return rows;
}

LossCause PointMeasurer::loss_cause(size_t unit, uint64_t new_crc_errors, const Action& a, bool invalid) const {
  // A line that went away and could not be reopened is not a silent unit: the driver gave up on it.
  if (!io_.unit(unit).sensor->connected()) return LossCause::link_failed;
  if (new_crc_errors > static_cast<uint64_t>(a.frames)) return LossCause::crc_storm;
  return invalid ? LossCause::invalid_frames : LossCause::silence;
}

uint64_t PointMeasurer::crc_errors(size_t unit) const {
  try {
    return io_.unit(unit).sensor->stats().crc_errors;
  } catch (const std::exception&) {
    return 0;
  }
}

void PointMeasurer::follower_ok(size_t ui) {
  io_.strikes(ui) = 0;
  if (crc_seen_.size() < io_.units()) crc_seen_.resize(io_.units(), 0);
  crc_seen_[ui] = crc_errors(ui);
}

void PointMeasurer::follower_failed(const Action& a, size_t ui, const std::string& why, int invalid) {
  const EngineUnit& u = io_.unit(ui);
  if (crc_seen_.size() < io_.units()) crc_seen_.resize(io_.units(), 0);
  const uint64_t crc = std::max(crc_errors(ui), crc_seen_[ui]);
  const uint64_t new_crc = crc - crc_seen_[ui];
  // A point without frames is forgiven as often as the stand re-measures a point; one more in a
  // row and the unit is dropped. Its stream is restarted once, at the first (a stopped stream comes
  // back; a silent unit costs its command timeouts only once).
  if (++io_.strikes(ui) > std::max(1, b_.max_remeasure)) {
    io_.lose(ui, loss_cause(ui, new_crc, a, invalid > 0), fmt::format("{} at {} points in a row, the last {}", why, io_.strikes(ui), a.describe()), a.point);
    return;
  }
  io_.warn(&a, fmt::format("unit {}: {} at {}{}", io_.unit_name(ui), why, a.describe(),
                           io_.strikes(ui) == 1 ? "; restarting its stream" : ""));
  if (io_.strikes(ui) > 1) return;
  try {
    Timed t(stats_.device_s);
    u.sensor->stop();
    u.sensor->flush();
    u.sensor->start();
  } catch (const DeviceError& e) {
    log_.warn("unit {} not answering while restarting: {}", io_.unit_name(ui), e.what());
  }
}

}  // namespace fpss
