// Driver overheads: ModbusGimbal::read_state against a bare libmodbus read of the same 15 input
// registers from the same in-process server on loopback; frame parser throughput.
#include <benchmark/benchmark.h>
#include <modbus.h>

#include <chrono>
#include <memory>
#include <random>

#include "drivers/fpss_frame.h"
#include "drivers/modbus_gimbal.h"
#include "modbus_test_server.h"

namespace {

using Clock = std::chrono::steady_clock;

fpss::test::ModbusTestServer& server() {
  static auto* s = [] {
    auto* srv = new fpss::test::ModbusTestServer();
    srv->set_recording(false);
    srv->set_input_i32(0, -123'456);
    srv->set_input_u64(10, 987'654'321);
    return srv;
  }();
  return *s;
}

struct BareContext {
  modbus_t* ctx;
  BareContext() {
    ctx = modbus_new_tcp("127.0.0.1", server().port());
    modbus_set_slave(ctx, 1);
    if (modbus_connect(ctx) != 0) throw std::runtime_error("bare connect failed");
  }
  ~BareContext() {
    modbus_close(ctx);
    modbus_free(ctx);
  }
};

std::unique_ptr<fpss::ModbusGimbal> driver() {
  fpss::GimbalOptions o;
  o.endpoint = server().endpoint();
  auto g = std::make_unique<fpss::ModbusGimbal>(o);
  g->connect();
  return g;
}

void BM_BareLibmodbusRead15(benchmark::State& state) {
  BareContext bare;
  uint16_t regs[15];
  for (auto _ : state) {
    if (modbus_read_input_registers(bare.ctx, 0, 15, regs) != 15) state.SkipWithError("bare read failed");
    benchmark::DoNotOptimize(regs);
  }
}
BENCHMARK(BM_BareLibmodbusRead15)->UseRealTime();

void BM_ModbusGimbalReadState(benchmark::State& state) {
  auto g = driver();
  for (auto _ : state) benchmark::DoNotOptimize(g->read_state());
}
BENCHMARK(BM_ModbusGimbalReadState)->UseRealTime();

// Both reads alternate in one loop, so drift in machine load hits both alike; reports the ratio.
void BM_ReadStateVsBare(benchmark::State& state) {
  BareContext bare;
  auto g = driver();
  uint16_t regs[15];
  Clock::duration t_bare{}, t_driver{};
  for (auto _ : state) {
    auto t0 = Clock::now();
    if (modbus_read_input_registers(bare.ctx, 0, 15, regs) != 15) state.SkipWithError("bare read failed");
    auto t1 = Clock::now();
    benchmark::DoNotOptimize(g->read_state());
    auto t2 = Clock::now();
    t_bare += t1 - t0;
    t_driver += t2 - t1;
  }
  const double n = static_cast<double>(state.iterations());
  const double bare_us = std::chrono::duration<double, std::micro>(t_bare).count() / n;
  const double driver_us = std::chrono::duration<double, std::micro>(t_driver).count() / n;
  state.counters["bare_us"] = bare_us;
  state.counters["driver_us"] = driver_us;
  state.counters["ratio"] = driver_us / bare_us;  // target <= 1.2
}
BENCHMARK(BM_ReadStateVsBare)->UseRealTime()->MinTime(2.0);

std::vector<uint8_t> frame_stream(std::size_t bytes) {
  std::vector<uint8_t> b;
  b.reserve(bytes + 300);
  std::mt19937 rng(5);
  uint16_t seq = 0;
  while (b.size() < bytes) {
    fpss::frame::append_sample(b, {seq, seq * 5000u, static_cast<int16_t>(rng()), static_cast<int16_t>(rng()), 7});
    if (++seq % 100 == 0) fpss::frame::append_reply(b, "TEMP 22.125");
  }
  return b;
}

// Arg: chunk size in bytes as the reader thread would see them (0: the whole buffer at once).
void BM_FrameParser(benchmark::State& state) {
  const auto data = frame_stream(8u << 20);
  const std::size_t chunk = state.range(0) ? static_cast<std::size_t>(state.range(0)) : data.size();
  uint64_t frames = 0;
  for (auto _ : state) {
    fpss::frame::Parser p;
    for (std::size_t i = 0; i < data.size(); i += chunk)
      p.feed(data.data() + i, std::min(chunk, data.size() - i), [&](const fpss::frame::Frame&) { ++frames; });
    benchmark::DoNotOptimize(frames);
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * data.size()));  // target >= 50 MB/s
  state.counters["frames/s"] = benchmark::Counter(static_cast<double>(frames), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_FrameParser)->Arg(64)->Arg(4096)->Arg(0)->Unit(benchmark::kMillisecond);

void BM_Crc16(benchmark::State& state) {
  std::vector<uint8_t> d(13, 0x5A);
  for (auto _ : state) benchmark::DoNotOptimize(fpss::frame::crc16_ccitt_false(d.data(), d.size()));
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * d.size()));
}
BENCHMARK(BM_Crc16);

}  // namespace
