// Emulator throughput: sensor frames per wall second off the pty at RATE 200 and --speed 50; Modbus reads per second.
#include <sys/resource.h>

#include <benchmark/benchmark.h>

#include <chrono>
#include <string>

#include "fixtures/emulator.h"
#include "tests/fixtures/wire_util.h"

namespace {

using Clock = std::chrono::steady_clock;

double process_cpu_s() {  // the emulator's threads and the reader: one process
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + (u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-6;
}

// A reader on the pty counts good frames for `seconds` of wall time. Target: rate * speed frames
// per wall second (200 Hz x 50 = 10,000), none lost to the emulator falling behind.
void BM_SensorStream(benchmark::State& state) {
  const int rate_hz = static_cast<int>(state.range(0));
  const double speed = static_cast<double>(state.range(1));
  const double seconds = 3.0;
  fpss::EmulatorOptions o;
  o.modbus_port = 0;
  o.speed = speed;
  fpss::Emulator emu(o);
  emu.start();
  fpss::wiretest::PtyHost host(emu.endpoints().sensor_pty);
  if (host.ask("RATE " + std::to_string(rate_hz)) != "OK" || host.ask("START") != "OK") {
    state.SkipWithError("sensor did not accept RATE/START");
    return;
  }
  host.read_until([&] { return host.scanner.samples.size() >= 100; }, 10.0);  // warm up
  for (auto _ : state) {
    const std::size_t n0 = host.scanner.samples.size();
    const auto s0 = emu.stats().sensor;
    const double b0 = emu.bench_time_s();
    const double cpu0 = process_cpu_s();
    const auto t0 = Clock::now();
    while (Clock::now() - t0 < std::chrono::duration<double>(seconds)) host.pump(5);
    const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
    const double bench = emu.bench_time_s() - b0;
    const auto s1 = emu.stats().sensor;
    const double frames = static_cast<double>(host.scanner.samples.size() - n0);
    state.counters["frames_per_wall_s"] = frames / wall;
    state.counters["target_per_wall_s"] = rate_hz * speed;
    state.counters["frames_per_bench_s"] = frames / bench;
    state.counters["bench_s_per_wall_s"] = bench / wall;
    state.counters["cpu_s_per_wall_s"] = (process_cpu_s() - cpu0) / wall;
    state.counters["dropped"] = static_cast<double>(s1.frames_dropped - s0.frames_dropped);
    state.counters["bad_crc"] = static_cast<double>(host.scanner.bad_crc());
    state.SetIterationTime(wall);
  }
  // seq must run without gaps: every generated frame arrived.
  const auto& s = host.scanner.samples;
  std::size_t gaps = 0;
  for (std::size_t i = 1; i < s.size(); ++i) gaps += static_cast<uint16_t>(s[i].seq - s[i - 1].seq) != 1;
  state.counters["seq_gaps"] = static_cast<double>(gaps);
}
BENCHMARK(BM_SensorStream)->Args({200, 50})->Args({50, 20})->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);

// A bare libmodbus read of the 15 input registers against the emulated gimbal on loopback.
void BM_ModbusReadState(benchmark::State& state) {
  fpss::EmulatorOptions o;
  o.modbus_port = 0;
  o.speed = 20;
  fpss::Emulator emu(o);
  emu.start();
  fpss::wiretest::ModbusClient c(emu.endpoints().modbus_port);
  for (auto _ : state) benchmark::DoNotOptimize(c.input(0, 15));
  state.counters["reads_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ModbusReadState)->Unit(benchmark::kMicrosecond);

}  // namespace
