#include "tests/support/fake_devices.h"

#include <fmt/format.h>

#include <cmath>
#include <thread>

namespace fpss::test {

namespace {
double host_now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
}  // namespace

FakeBench::FakeBench(BenchConfig cfg, double speed) : bench_(std::move(cfg)), speed_(speed) {}

void FakeBench::use_virtual_clock(double request_s) {
  virtual_ = true;
  request_s_ = request_s;
}

void FakeBench::host_stalls(uint64_t seed, double probability, double max_s) {
  stall_rng_.seed(seed);
  stall_probability_ = probability;
  stall_max_s_ = max_s;
}

void FakeBench::charge_request() {
  if (!virtual_) return;
  double away_s = 0;
  if (stall_probability_ > 0 && std::uniform_real_distribution<double>(0, 1)(stall_rng_) < stall_probability_) {
    away_s = std::uniform_real_distribution<double>(0, stall_max_s_)(stall_rng_);
  }
  advance_to(virtual_t_ + away_s + request_s_);
}

void FakeBench::advance_to(double t_s) {
  virtual_t_ = std::max(virtual_t_, t_s);
  bench_.advance_to(virtual_t_);
}

double FakeBench::now_s() {
  if (virtual_) return bench_.time_s();
  const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count() * speed_;
  bench_.advance_to(std::max(t, bench_.time_s()));
  return bench_.time_s();
}

void FakeGimbal::request() {
  if (!connected_) throw DeviceError("fake gimbal: not connected");
  ++requests_;
  b_.charge_request();
  b_.now_s();
  b_.bench().note_request();
  if (b_.following_error_at_request != 0 && requests_ == b_.following_error_at_request) b_.bench().inject_fault(1);
}

GimbalState FakeGimbal::read_state() {
  std::lock_guard lock(b_.mutex());
  request();
  const GimbalReadout r = b_.bench().gimbal();
  GimbalState s;
  s.pitch_arcsec = r.pitch_arcsec;
  s.yaw_arcsec = r.yaw_arcsec;
  s.pitch_rate_arcsec_s = r.pitch_rate_arcsec_s;
  s.yaw_rate_arcsec_s = r.yaw_rate_arcsec_s;
  s.status = r.status;
  s.fault = static_cast<GimbalFault>(r.fault_code);
  s.sample_time_us = r.time_us;
  s.moves_completed = r.moves_completed;
  s.host_time_s = host_now_s();
  return s;
}

void FakeGimbal::set_max_rate(double arcsec_s) {
  if (!(arcsec_s > 0) || arcsec_s > limits_.max_rate_arcsec_s) {
    throw LimitError(fmt::format("fake gimbal: rate {} arcsec/s beyond the limit", arcsec_s));
  }
  std::lock_guard lock(b_.mutex());
  request();
  b_.bench().set_max_rate(arcsec_s);
}

void FakeGimbal::move_to(double pitch_arcsec, double yaw_arcsec) {
  check_limits(pitch_arcsec, yaw_arcsec);
  std::lock_guard lock(b_.mutex());
  request();
  if (b_.bench().set_target(pitch_arcsec, yaw_arcsec) != Bench::Reply::ok) throw DeviceError("fake gimbal: target refused");
  b_.bench().command(1);
  last_command_ = 1;
}

void FakeGimbal::check_limits(double pitch_arcsec, double yaw_arcsec) const {
  if (pitch_arcsec < limits_.pitch_min_arcsec || pitch_arcsec > limits_.pitch_max_arcsec ||
      yaw_arcsec < limits_.yaw_min_arcsec || yaw_arcsec > limits_.yaw_max_arcsec) {
    throw LimitError(fmt::format("fake gimbal: target {}, {} arcsec beyond the soft limits", pitch_arcsec, yaw_arcsec));
  }
}

void FakeGimbal::move_at(double pitch_arcsec, double yaw_arcsec, uint64_t start_us) {
  if (!timed_moves()) Gimbal::move_at(pitch_arcsec, yaw_arcsec, start_us);
  check_limits(pitch_arcsec, yaw_arcsec);
  std::lock_guard lock(b_.mutex());
  request();
  request();
  request();
  if (b_.bench().set_target(pitch_arcsec, yaw_arcsec) != Bench::Reply::ok) throw DeviceError("fake gimbal: target refused");
  if (b_.bench().command_move_at(static_cast<double>(start_us) * 1e-6) != Bench::Reply::ok) {
    throw DeviceError("fake gimbal: move at a set time refused (a time past, rate mode, or faulted)");
  }
  last_command_ = 6;
}

std::optional<GimbalCommand> FakeGimbal::read_command() {
  std::lock_guard lock(b_.mutex());
  request();
  GimbalCommand c;
  c.target_pitch_arcsec = b_.bench().target_pitch_arcsec();
  c.target_yaw_arcsec = b_.bench().target_yaw_arcsec();
  c.max_rate_arcsec_s = b_.bench().max_rate_arcsec_s();
  c.watchdog_s = b_.bench().watchdog_s();
  c.command = last_command_;
  return c;
}

void FakeGimbal::foreign_max_rate(double arcsec_s) {
  std::lock_guard lock(b_.mutex());
  b_.now_s();
  b_.bench().set_max_rate(arcsec_s);
}

GimbalState FakeGimbal::wait_in_position(double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    const GimbalState s = read_state();
    if (s.has(kFault)) throw DeviceError("fake gimbal: fault while waiting");
    if (s.has(kInPosition) && !s.has(kMoving)) return s;
    if (std::chrono::steady_clock::now() > end) throw DeviceError("fake gimbal: not in position in time");
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

void FakeGimbal::start_rate(double pitch_arcsec_s, double yaw_arcsec_s) {
  std::lock_guard lock(b_.mutex());
  request();
  b_.bench().set_rate_command(pitch_arcsec_s, yaw_arcsec_s);
  b_.bench().command(5);
  last_command_ = 5;
}

void FakeGimbal::set_watchdog(double seconds) {
  std::lock_guard lock(b_.mutex());
  request();
  b_.bench().set_watchdog(seconds);
}

void FakeGimbal::command(uint16_t code) {
  std::lock_guard lock(b_.mutex());
  request();
  b_.bench().command(code);
  last_command_ = code;
}

std::string FakeSensor::identify() {
  const auto& c = b_.bench().config();
  return fmt::format("FPSS,SN={},FW={}", c.serial, c.firmware);
}

void FakeSensor::set_rate(int hz) {
  if (hz < 1 || hz > 200) throw DeviceError("fake sensor: rate out of range");
  rate_hz_ = hz;
}

void FakeSensor::start() {
  streaming_ = true;
  flush();
}

double FakeSensor::temperature_c() {
  std::lock_guard lock(b_.mutex());
  b_.charge_request();
  return b_.bench().temperature_c(b_.now_s());
}

void FakeSensor::flush() {
  std::lock_guard lock(b_.mutex());
  next_frame_ = static_cast<uint64_t>(std::floor(b_.now_s() * rate_hz_)) + 1;
}

std::optional<SensorSample> FakeSensor::next_sample(double timeout_s) {
  using Dur = std::chrono::steady_clock::duration;
  if (!connected_) throw DeviceError("fake sensor: not connected");
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration_cast<Dur>(std::chrono::duration<double>(timeout_s));
  for (;;) {
    double now = 0;
    {
      std::lock_guard lock(b_.mutex());
      now = b_.now_s();
      if (streaming_ && b_.virtual_clock() && timeout_s > 0) {
        b_.advance_to(frame_time_s(next_frame_));  // waiting for the frame is what moves the clock
        now = b_.now_s();
      }
      if (streaming_ && frame_time_s(next_frame_) <= now) {
        const uint64_t k = next_frame_++;
        const SensorReading r = b_.bench().sensor_at(frame_time_s(k), k);
        SensorSample s;
        s.seq = static_cast<uint16_t>(k);
        s.sensor_time_us = static_cast<uint32_t>(std::llround(r.time_s * 1e6));
        s.sensor_time_s = r.time_s;
        s.counts_alpha = r.counts_alpha;
        s.counts_beta = r.counts_beta;
        const bool spoiled = b_.invalid_frame_every > 0 && k % b_.invalid_frame_every == 0;
        s.status = r.time_s >= b_.invalid_frames_from_s || spoiled ? 0 : r.status;
        s.host_time_s = host_now_s();
        ++stats_.frames;
        return s;
      }
    }
    const auto left = end - std::chrono::steady_clock::now();
    if (left <= std::chrono::steady_clock::duration::zero()) return std::nullopt;
    const double until_next_s = streaming_ ? (frame_time_s(next_frame_) - now) / b_.speed() : 1e-3;
    const Dur until_next = std::chrono::duration_cast<Dur>(std::chrono::duration<double>(std::max(until_next_s, 50e-6)));
    std::this_thread::sleep_for(std::min<Dur>(left, until_next));
  }
}

}  // namespace fpss::test
