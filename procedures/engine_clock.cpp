#include "procedures/engine_clock.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <string>

#include "procedures/align.h"

namespace fpss {

namespace {
// Seconds since an ISO 8601 UTC time (2024-05-01T12:00:00Z); 0 when it cannot be read.
double seconds_since_utc(const std::string& iso) {
  std::tm tm{};
  if (iso.empty() || !strptime(iso.c_str(), "%Y-%m-%dT%H:%M:%SZ", &tm)) return 0;
  const std::time_t then = timegm(&tm);
  return std::max(0.0, std::difftime(std::time(nullptr), then));
}
}  // namespace

void EngineClock::start(const ResumePoint& from) {
  host_t0_ = host_now_s();
  time_base_ = last_time_ = from.last_time_s;
  if (!from.last_utc.empty()) {
    time_base_ += seconds_since_utc(from.last_utc) * b_.time_scale;
  }
}

double EngineClock::host_now_s() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

void EngineClock::note_bench(double bench_s, double host_s) {
  // The devices' stamps are the truth (the host's estimate between them may run ahead); never
  // backwards: a late stamp of an earlier instant says nothing new.
  if (bench_s >= last_bench_s_) {
    last_bench_s_ = bench_s;
    last_bench_host_s_ = host_s;
  }
}

void EngineClock::note_gimbal(double gimbal_s, double host_s) {
  last_gimbal_time_s_ = gimbal_s;
  note_bench(gimbal_s, host_s);
  if (bench_start_s_ < 0) bench_start_s_ = gimbal_s;
}

double EngineClock::bench_now_at(double host_s) const {
  if (last_bench_host_s_ <= 0) return last_bench_s_;
  return last_bench_s_ + std::max(0.0, host_s - last_bench_host_s_) * b_.time_scale;
}

double EngineClock::sensor_clock_s(const SensorSample& f, double offset_s) const {
  const double t = b_.clock == ClockSync::shared ? unwrap_near(f.sensor_time_us, last_gimbal_time_s_)
                                                 : f.sensor_time_s;
  return std::round((t + offset_s) * 1e6) / 1e6;
}

void FrameTakenClock::note(const SensorSample& f) {
  constexpr double kDrift = 1e-4;  // the clocks' relative rate, at most (crystals are within 50 ppm)
  const double delay = f.host_time_s - f.sensor_time_s / time_scale_;
  if (!link_delay_s_ || f.sensor_time_s < last_sensor_s_) {
    link_delay_s_ = delay;  // the first frame, or the sensor's clock restarted
  } else {
    link_delay_s_ = std::min(delay, *link_delay_s_ + kDrift * (f.host_time_s - last_host_s_));
  }
  last_sensor_s_ = f.sensor_time_s;
  last_host_s_ = f.host_time_s;
}

double FrameTakenClock::taken_host_s(const SensorSample& f) const {
  if (!link_delay_s_) return f.host_time_s;
  return std::min(f.host_time_s, f.sensor_time_s / time_scale_ + *link_delay_s_);
}

double EngineClock::stand_time(double sensor_time_s) {
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

double EngineClock::first_frame_from(double t_s) const {
  const double period_s = 1.0 / b_.sample_rate_hz;
  return frame_grid_s_ + std::ceil((t_s - frame_grid_s_) / period_s - 1e-6) * period_s;
}

double EngineClock::dwell_end_s(const Action& a, double first_frame_s) const {
  return first_frame_s + (a.frames - 0.5) * (1.0 / b_.sample_rate_hz);
}

std::optional<double> EngineClock::bench_s() const {
  if (bench_start_s_ < 0) return std::nullopt;
  return std::max(0.0, last_bench_s_ - bench_start_s_ - off_bench_s_);
}

}  // namespace fpss
