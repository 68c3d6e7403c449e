// The engine with the real drivers against the emulated bench over the real wire (Modbus TCP on
// loopback, the sensor's pty): what only the device boundary shows, another client moving the
// gimbal and a sensor reporting an implausible temperature.
#include <gtest/gtest.h>
#include <modbus.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "calib/samples.h"
#include "drivers/endpoints.h"
#include "fixtures/emulator.h"
#include "procedures/engine.h"
#include "tests/drivers/driver_options.h"
#include "tests/procedures/engine_fixture.h"
#include "tests/support/emulator_options.h"

namespace fpss {
namespace {

using test::TempDir;
namespace fs = std::filesystem;

constexpr double kSpeed = 20;

// The emulator, the real drivers on its endpoints, the grid's plan, a recorder of `run_dir`.
struct EmulatedBench {
  EmulatedBench(const fs::path& run_dir, BenchConfig cfg = default_bench_config()) : emu(options(std::move(cfg))) {
    emu.start();
    GimbalOptions go = e2e::gimbal_options(emu.endpoints().gimbal());
    go.timed_moves = true;
    gimbal = make_gimbal(go);
    sensor = make_sensor(e2e::sensor_options(emu.endpoints().sensor()));
    gimbal->connect();
    sensor->connect();
    // What stand/config's emulated stand sets: one bench clock, its speed, the link's round trip.
    settings.clock = ClockSync::shared;
    settings.time_scale = kSpeed;
    settings.link_round_trip_s = 30e-6;
    settings.timed_moves = true;
    settings.axes = AxisMapping{};
    plan = test::plan_of(test::grid(), settings);
    recorder = std::make_unique<RunRecorder>(run_dir);
    record_with(bus, *recorder);
    bus.subscribe([this](const Event& e) {
      if (const auto* f = std::get_if<Fault>(&e)) warnings.push_back(f->message);
      if (const auto* p = std::get_if<PointStarted>(&e)) started.push_back(p->point.index);
    });
  }
  static EmulatorOptions options(BenchConfig cfg) {
    EmulatorOptions o = test::running_emulator_options(kSpeed);
    o.bench = std::move(cfg);
    return o;
  }
  EngineResult run() {
    Engine engine(*gimbal, *sensor, settings, plan, bus, *log, ctl, hooks);
    return engine.run();
  }
  Emulator emu;
  std::unique_ptr<Gimbal> gimbal;
  std::unique_ptr<Sensor> sensor;
  EngineSettings settings;
  Plan plan;
  EventBus bus;
  std::unique_ptr<RunRecorder> recorder;
  RunControl ctl;
  EngineHooks hooks;
  std::shared_ptr<spdlog::logger> log = test::quiet_log();
  std::vector<std::string> warnings;
  std::vector<int64_t> started;
};

// A second Modbus TCP client, as an operator's tool would be: writes the targets and command 1.
void move_from_another_client(const std::string& endpoint, double pitch_arcsec, double yaw_arcsec) {
  const Endpoint ep = parse_endpoint(endpoint);
  modbus_t* ctx = modbus_new_tcp(ep.host.c_str(), ep.port);
  ASSERT_NE(ctx, nullptr);
  ASSERT_EQ(modbus_set_slave(ctx, 1), 0);
  ASSERT_EQ(modbus_connect(ctx), 0) << modbus_strerror(errno);
  auto words = [](double arcsec) {
    const auto mas = static_cast<uint32_t>(static_cast<int32_t>(std::lround(arcsec * 1000)));
    return std::vector<uint16_t>{static_cast<uint16_t>(mas >> 16), static_cast<uint16_t>(mas & 0xFFFF)};
  };
  std::vector<uint16_t> regs = words(pitch_arcsec);
  const std::vector<uint16_t> y = words(yaw_arcsec);
  regs.insert(regs.end(), y.begin(), y.end());
  EXPECT_EQ(modbus_write_registers(ctx, 0, 4, regs.data()), 4) << modbus_strerror(errno);
  EXPECT_EQ(modbus_write_register(ctx, 11, 1), 1) << modbus_strerror(errno);
  modbus_close(ctx);
  modbus_free(ctx);
}

TEST(EngineOnEmulator, AnotherClientMovingTheGimbalStopsTheRunNamingWhereItWasFound) {
  TempDir tmp("engine-emu-foreign");
  EmulatedBench bench(tmp / "run");
  // When point 3's first attempt begins (on the engine's thread, so always at the same place in
  // the run), another client sends the gimbal to +1.9 deg pitch, beyond every target of the plan.
  bool moved = false;
  bench.bus.subscribe([&](const Event& e) {
    const auto* p = std::get_if<PointStarted>(&e);
    if (!p || p->point.index != 2 || moved) return;
    moved = true;
    move_from_another_client(bench.emu.endpoints().gimbal(), 1.9 * 3600, 0);
  });
  const EngineResult r = bench.run();
  ASSERT_TRUE(moved);
  std::printf("stopped: %s\n", r.reason.c_str());
  EXPECT_EQ(r.outcome, RunOutcome::failed) << r.reason;
  EXPECT_EQ(r.cause, StopCause::commanded_elsewhere) << r.reason;
  EXPECT_NE(r.reason.find("gimbal found at "), std::string::npos) << r.reason;
  EXPECT_NE(r.reason.find("arcsec, which this run never commanded: another client?"), std::string::npos) << r.reason;
  // Stopped at the first sight of it: one attempt at point 3, no re-measurement, safely at null.
  EXPECT_EQ(r.points_done, 2);
  EXPECT_EQ(std::count(bench.started.begin(), bench.started.end(), 2), 1);
  EXPECT_TRUE(r.safe_state);
  const GimbalReadout g = bench.emu.with_bench([](Bench& b) { return b.gimbal_noiseless(); });
  EXPECT_NEAR(g.pitch_arcsec, 0, 1.0);
  EXPECT_NEAR(g.yaw_arcsec, 0, 1.0);
}

TEST(EngineOnEmulator, AnImplausibleTemperatureIsNeverRecordedAndEachPointSaysWhy) {
  TempDir tmp("engine-emu-temp");
  BenchConfig cfg = default_bench_config();
  cfg.temperature.ramp_c_per_s = 0;
  cfg.temperature.t0_c = 2021.002;  // steady: the emulator answers "TEMP 2021.00" (two decimals)
  EmulatedBench bench(tmp / "run", cfg);
  const EngineResult r = bench.run();
  EXPECT_EQ(r.outcome, RunOutcome::completed) << r.reason;
  const SampleTable t = read_samples_csv(tmp / "run" / "samples.csv");
  ASSERT_EQ(t.size(), bench.plan.points * 4);
  for (double c : t.numeric_column("temperature_c")) EXPECT_TRUE(std::isnan(c)) << c;
  int said = 0;
  for (const auto& w : bench.warnings) {
    if (w.find("sensor temperature 2021.00 °C outside the plausible range -60..100 °C") != std::string::npos) ++said;
  }
  EXPECT_EQ(said, static_cast<int>(bench.plan.points));
}

}  // namespace
}  // namespace fpss
