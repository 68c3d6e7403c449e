// In-process fake Gimbal and Sensor (after ros2_control's mock_components), driven by the simulated bench's physics.
#pragma once
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <random>

#include "drivers/gimbal.h"
#include "drivers/sensor.h"
#include "fixtures/bench.h"

namespace fpss::test {

// One simulated bench shared by both fakes. Its clock is the wall clock since construction times
// `speed`, as the emulator's real-time clock is, so the engine's waits mean what they mean on a
// real stand; but there is no wire, no child process and no pty.
class FakeBench {
 public:
  explicit FakeBench(BenchConfig cfg = default_bench_config(), double speed = 20);
  // Brings the physics up to now and returns the bench time.
  double now_s();
  // A virtual clock instead: bench time moves only when a device is asked (each gimbal request
  // and sensor command costs `request_s` of bench time, a link's round trip at some speed-up) and
  // when the sensor's next frame is waited for. Whatever the host does, the same run takes the
  // same bench time: what a controller's waiting costs, in bench seconds, to the microsecond.
  void use_virtual_clock(double request_s);
  bool virtual_clock() const { return virtual_; }
  // Virtual clock: a busy host. Before a request, with `probability`, the host was away for a
  // time drawn uniformly up to `max_s` of bench time (seeded): what a descheduled controller
  // costs at a speed-up, where a millisecond of wall time is a second of bench time at 1000x.
  void host_stalls(uint64_t seed, double probability, double max_s);
  // Virtual clock: a request's round trip, or a wait up to bench time t_s.
  void charge_request();
  void advance_to(double t_s);
  Bench& bench() { return bench_; }
  std::mutex& mutex() { return mu_; }
  double speed() const { return speed_; }
  // Faults on demand: the gimbal's following error at its n-th request (1-based; 0 never), and
  // invalid sensor frames (sun absent) from bench time t on (infinite: never).
  uint64_t following_error_at_request = 0;
  double invalid_frames_from_s = 1e300;
  uint64_t invalid_frame_every = 0;  // every n-th frame (by index) invalid, sun absent (0: none)

 private:
  std::mutex mu_;
  Bench bench_;
  double speed_;
  bool virtual_ = false;
  double request_s_ = 0, virtual_t_ = 0;  // the virtual clock, exact (the bench keeps whole ticks)
  std::mt19937_64 stall_rng_;
  double stall_probability_ = 0, stall_max_s_ = 0;
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
};

class FakeGimbal : public Gimbal {
 public:
  FakeGimbal(FakeBench& bench, SoftLimits limits = {}) : b_(bench), limits_(limits) {}
  void connect() override { connected_ = true; }
  void disconnect() override { connected_ = false; }
  bool connected() const override { return connected_; }
  GimbalState read_state() override;
  void set_max_rate(double arcsec_s) override;
  void move_to(double pitch_arcsec, double yaw_arcsec) override;
  bool timed_moves() const override { return b_.bench().config().timed_moves; }
  // Three requests, as the Modbus driver sends: the targets, the start time, the command.
  void move_at(double pitch_arcsec, double yaw_arcsec, uint64_t start_us) override;
  GimbalState wait_in_position(double timeout_s) override;
  void start_rate(double pitch_arcsec_s, double yaw_arcsec_s) override;
  void stop() override { command(2); }
  void home() override { command(3); }
  void clear_fault() override { command(4); }
  void set_watchdog(double seconds) override;
  std::optional<GimbalCommand> read_command() override;
  uint64_t requests() const { return requests_; }
  // Another client's write, as a second Modbus master on the same gimbal would make it.
  void foreign_max_rate(double arcsec_s);

 private:
  void request();  // counts a request; fires the following error when it is due
  void check_limits(double pitch_arcsec, double yaw_arcsec) const;  // LimitError beyond the soft limits
  void command(uint16_t code);
  FakeBench& b_;
  SoftLimits limits_;
  bool connected_ = false;
  uint64_t requests_ = 0;
  uint16_t last_command_ = 0;
};

class FakeSensor : public Sensor {
 public:
  explicit FakeSensor(FakeBench& bench) : b_(bench) {}
  void connect() override { connected_ = true; }
  void disconnect() override { connected_ = false; }
  bool connected() const override { return connected_; }
  std::string identify() override;
  void set_rate(int hz) override;
  void start() override;
  void stop() override { streaming_ = false; }
  double temperature_c() override;
  std::optional<SensorSample> next_sample(double timeout_s) override;
  void flush() override;
  SensorStats stats() const override { return stats_; }

 private:
  double frame_time_s(uint64_t k) const { return static_cast<double>(k) / rate_hz_; }
  FakeBench& b_;
  bool connected_ = false, streaming_ = false;
  double rate_hz_ = 50;
  uint64_t next_frame_ = 0;
  SensorStats stats_;
};

}  // namespace fpss::test
