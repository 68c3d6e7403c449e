// The procedure engine's speed: the discrete grid end to end against the emulator (the binary,
// over Modbus TCP and a pty, default speed-up 20), and the controller's own work per point with
// devices that answer at once, so nothing but the controller is measured.
#include <benchmark/benchmark.h>
#include <spdlog/sinks/null_sink.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>

#include <fmt/format.h>

#include "calib/calibrator.h"
#include "calib/coefficients.h"
#include "calib/transfer_function.h"
#include "calib/units.h"
#include "procedures/engine.h"
#include "procedures/plan.h"
#include "procedures/procedure.h"
#include "procedures/recorder.h"
#include "tests/procedures/run_util.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double now_s() { return std::chrono::duration<double>(Clock::now().time_since_epoch()).count(); }

// `fpss-stand run procedures/discrete_grid.yaml --emulate` as a user runs it.
void BM_DiscreteGridEmulated(benchmark::State& state) {
  fpss::test::TempDir tmp("bench-grid");
  nlohmann::json engine;
  int64_t points = 0;
  int n = 0;
  for (auto _ : state) {
    const fs::path runs = tmp / ("runs" + std::to_string(n++));
    const auto t0 = Clock::now();
    const auto r = fpss::test::run_stand({"run", (fpss::test::source_dir() / "procedures" / "discrete_grid.yaml").string(),
                                          "--emulate", "--runs-dir", runs.string(), "--quiet"},
                                         tmp.path(), "grid", 300);
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - t0).count());
    if (r.code != 0) {
      state.SkipWithError(("run failed: " + r.err).c_str());
      return;
    }
    const auto doc = fpss::read_json_file(fpss::test::run_dirs(runs).front() / "run.json");
    engine = doc["sessions"][0]["engine"];
    points = doc["points"]["completed"].get<int64_t>();
  }
  const double p = static_cast<double>(points);
  state.counters["points"] = p;
  state.counters["own_ms_per_point"] = engine["own_s"].get<double>() / p * 1e3;
  state.counters["storage_ms_per_point"] = engine["storage_s"].get<double>() / p * 1e3;
  state.counters["device_ms_per_point"] = engine["device_s"].get<double>() / p * 1e3;
  state.counters["sleep_ms_per_point"] = engine["sleep_s"].get<double>() / p * 1e3;
  state.counters["calibrate_s"] = engine["calibrate_s"].get<double>();
}
BENCHMARK(BM_DiscreteGridEmulated)->Iterations(2)->UseManualTime()->Unit(benchmark::kSecond);

// The speed sweep: `fpss-stand run procedures/discrete_grid.yaml --emulate --speed K` for K = 20,
// 100, 1000. The run's bench time (run.json, engine bench_s: the devices' clock from the first
// reading to the gimbal back at null, the calibrate and check steps left out) against the physical
// minimum the dry run prints (the moves at the gimbal's rate and acceleration, the settles and the
// dwells; engine physical_s), the dry run's estimate (estimated_s: the minimum plus the links'
// round trips at the speed-up), and the command's wall time. Targets: ratio <= 1.1 and the dry
// run's estimate within 5 % of the bench time at every speed; under 0.5 s of wall at 1000.
void BM_DiscreteGridAtSpeed(benchmark::State& state) {
  const auto speed = std::to_string(state.range(0));
  fpss::test::TempDir tmp("bench-speed");
  const std::string grid = (fpss::test::source_dir() / "procedures" / "discrete_grid.yaml").string();
  const auto dry = fpss::test::run_stand({"run", grid, "--emulate", "--speed", speed, "--dry-run"}, tmp.path(), "dry", 60);
  double bench = 0, physical = 0, estimate = 0, wall = 0;
  int n = 0;
  for (auto _ : state) {
    const fs::path runs = tmp / ("runs" + std::to_string(n++));
    const auto t0 = Clock::now();
    const auto r = fpss::test::run_stand({"run", grid, "--emulate", "--speed", speed, "--runs-dir", runs.string(), "--quiet"},
                                         tmp.path(), "grid", 300);
    const double w = std::chrono::duration<double>(Clock::now() - t0).count();
    state.SetIterationTime(w);
    if (r.code != 0) {
      state.SkipWithError(("run failed: " + r.err).c_str());
      return;
    }
    const auto engine = fpss::read_json_file(fpss::test::run_dirs(runs).front() / "run.json")["sessions"][0]["engine"];
    bench += engine["bench_s"].get<double>();
    physical = engine["physical_s"].get<double>();
    estimate = engine["estimated_s"].get<double>();
    wall += w;
  }
  bench /= n;
  wall /= n;
  state.counters["bench_s"] = bench;
  state.counters["physical_min_s"] = physical;
  state.counters["ratio"] = bench / physical;
  state.counters["estimate_s"] = estimate;
  state.counters["estimate_err_pct"] = 100 * (estimate - bench) / bench;
  state.counters["wall_s"] = wall;
  if (dry.out.find("estimated duration:") == std::string::npos) state.SkipWithError("the dry run printed no estimate");
}
BENCHMARK(BM_DiscreteGridAtSpeed)->Arg(20)->Arg(100)->Arg(1000)->Iterations(3)->UseManualTime()->Unit(benchmark::kSecond);

// Units per bench hour (docs/procedures.md, "Several units"): `run --emulate --bench` with 1, 2 and
// 4 units of different published truths in one pass, with the shipped grid (arg 1 = 0) and with
// the procedure `design` makes for the grid's accuracy (arg 1 = 1: the largest 1-sigma the grid
// reaches, 0.03 arcsec). Bench time is run.json's engine bench_s; every unit's fit is held against
// its truth over +-0.4 deg (worst_error_arcsec). Target: at least 150 units per bench hour at the
// grid's accuracy.
void BM_UnitsPerBenchHour(benchmark::State& state) {
  const int units = static_cast<int>(state.range(0));
  const bool designed = state.range(1) == 1;
  fpss::test::TempDir tmp("bench-units");
  const char* truths[] = {"a-6-fpss1", "a-6-fpss2", "a-5-fpss1", "a-5-fpss2"};
  std::string bench = "seed: 3\nsensors:\n";
  for (int u = 0; u < units; ++u) {
    bench += fmt::format("  - {{serial: U{}, truth: {}/calib/data/published/{}.json}}\n", u + 1,
                         fpss::test::source_dir().string(), truths[u]);
  }
  const fs::path bench_file = tmp.write("bench.yaml", bench);
  std::string procedure = (fpss::test::source_dir() / "procedures" / "discrete_grid.yaml").string();
  if (designed) {
    procedure = (tmp / "designed.yaml").string();
    const auto d = fpss::test::run_stand({"design", "--target-sigma-arcsec", "0.03", "--emulate", "--bench",
                                          bench_file.string(), "--out", procedure},
                                         tmp.path(), "design", 300);
    if (d.code != 0) {
      state.SkipWithError(("design failed: " + d.err).c_str());
      return;
    }
  }
  double bench_s = 0, worst = 0;
  int n = 0;
  for (auto _ : state) {
    const fs::path runs = tmp / ("runs" + std::to_string(n++));
    const auto t0 = Clock::now();
    const auto r = fpss::test::run_stand({"run", procedure, "--emulate", "--bench", bench_file.string(), "--speed", "200",
                                          "--runs-dir", runs.string(), "--quiet"},
                                         tmp.path(), "run", 300);
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - t0).count());
    if (r.code != 0) {
      state.SkipWithError(("run failed: " + r.err).c_str());
      return;
    }
    const fs::path dir = fpss::test::run_dirs(runs).front();
    bench_s += fpss::read_json_file(dir / "run.json")["sessions"][0]["engine"]["bench_s"].get<double>();
    for (int u = 0; u < units; ++u) {
      const fs::path cal = units == 1 ? dir / "calibration.json" : dir / "units" / ("U" + std::to_string(u + 1)) / "calibration.json";
      const fpss::CoefficientSet fit = fpss::load_coefficients(cal), truth = fpss::load_published(truths[u]);
      for (auto axis : {&fpss::CoefficientSet::alpha, &fpss::CoefficientSet::beta}) {
        const fpss::AxisModel t(truth.*axis);
        const double lo = t.counts_for_angle(fpss::arcsec_to_rad(-1440)), hi = t.counts_for_angle(fpss::arcsec_to_rad(1440));
        worst = std::max(worst, fpss::compare_transfer(fit.*axis, truth.*axis, std::min(lo, hi), std::max(lo, hi)).max_abs_arcsec);
      }
    }
  }
  bench_s /= n;
  state.counters["units"] = units;
  state.counters["bench_s"] = bench_s;
  state.counters["units_per_bench_hour"] = units * 3600.0 / bench_s;
  state.counters["worst_error_arcsec"] = worst;
}
BENCHMARK(BM_UnitsPerBenchHour)
    ->ArgsProduct({{1, 2, 4}, {0, 1}})
    ->ArgNames({"units", "designed"})
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kSecond);

// Devices that are always where they were told to be and always have a frame ready.
class InstantGimbal : public fpss::Gimbal {
 public:
  void connect() override {}
  void disconnect() override {}
  bool connected() const override { return true; }
  fpss::GimbalState read_state() override {
    fpss::GimbalState s;
    s.pitch_arcsec = p_;
    s.yaw_arcsec = y_;
    s.status = fpss::kHomed | fpss::kInPosition;
    s.sample_time_us = (t_us_ += 1000);
    s.host_time_s = now_s();
    return s;
  }
  void set_max_rate(double) override {}
  void move_to(double p, double y) override { p_ = p, y_ = y; }
  fpss::GimbalState wait_in_position(double) override { return read_state(); }
  void start_rate(double, double) override {}
  void stop() override {}
  void home() override { p_ = y_ = 0; }
  void clear_fault() override {}
  void set_watchdog(double) override {}

 private:
  double p_ = 0, y_ = 0;
  uint64_t t_us_ = 0;
};

class InstantSensor : public fpss::Sensor {
 public:
  void connect() override {}
  void disconnect() override {}
  bool connected() const override { return true; }
  std::string identify() override { return "FPSS,SN=BENCH,FW=0"; }
  void set_rate(int) override {}
  void start() override {}
  void stop() override {}
  double temperature_c() override { return 20.0; }
  std::optional<fpss::SensorSample> next_sample(double) override {
    fpss::SensorSample s;
    s.seq = static_cast<uint16_t>(n_);
    s.sensor_time_us = static_cast<uint32_t>(n_ * 20000);
    s.sensor_time_s = static_cast<double>(n_) * 0.02;
    s.counts_alpha = static_cast<int16_t>(n_ % 1000);
    s.counts_beta = static_cast<int16_t>(-(n_ % 1000));
    s.status = fpss::kSunPresent | fpss::kAlphaValid | fpss::kBetaValid;
    s.host_time_s = now_s();
    ++n_;
    return s;
  }
  void flush() override {}
  fpss::SensorStats stats() const override { return {}; }

 private:
  uint64_t n_ = 0;
};

// The engine over the discrete grid's 113 points with instant devices, a real recorder
// (samples.csv and the journal synced at every point) and events.jsonl: what the controller costs per point.
void BM_EngineControllerPerPoint(benchmark::State& state) {
  fpss::test::TempDir tmp("bench-engine");
  const fpss::Procedure proc =
      fpss::load_procedure(fpss::test::source_dir() / "procedures" / "discrete_grid.yaml");
  fpss::EngineSettings b;
  b.time_scale = 1e12;  // settle times become nothing: only the controller is left
  b.clock = fpss::ClockSync::shared;
  fpss::Diagnostics d("bench");
  const fpss::Plan plan = fpss::expand(proc, b, d);
  auto log = std::make_shared<spdlog::logger>("bench", std::make_shared<spdlog::sinks::null_sink_mt>());
  InstantGimbal g;
  InstantSensor s;
  fpss::EngineStats total;
  int n = 0;
  for (auto _ : state) {
    fpss::RunRecorder rec(tmp / ("run" + std::to_string(n++)));
    // The session's subscribers that run per point: the recorder and events.jsonl.
    fpss::EventBus bus;
    fpss::record_with(bus, rec);
    fpss::EventLog events(rec.dir() / "events.jsonl");
    bus.subscribe([&](const fpss::Event& e) { events.write(e); });
    fpss::RunControl ctl;
    fpss::EngineHooks hooks;  // no calibrate: the fit is timed by the calibrator's own benchmark
    fpss::Engine engine(g, s, b, plan, bus, *log, ctl, hooks);
    const auto r = engine.run();
    if (r.outcome != fpss::RunOutcome::completed) {
      state.SkipWithError(r.reason.c_str());
      return;
    }
    const auto& st = engine.stats();
    total.wall_s += st.wall_s;
    total.device_s += st.device_s;
    total.sleep_s += st.sleep_s;
    total.storage_s += st.storage_s;
    total.points += st.points;
  }
  const double p = static_cast<double>(total.points);
  state.counters["own_ms_per_point"] = total.own_s() / p * 1e3;
  state.counters["storage_ms_per_point"] = total.storage_s / p * 1e3;
  state.counters["wall_ms_per_point"] = total.wall_s / p * 1e3;
}
BENCHMARK(BM_EngineControllerPerPoint)->Iterations(5)->Unit(benchmark::kMillisecond);

void BM_ParseAndExpandDiscreteGrid(benchmark::State& state) {
  const std::string text =
      fpss::test::read_file(fpss::test::source_dir() / "procedures" / "discrete_grid.yaml");
  fpss::EngineSettings b;
  for (auto _ : state) {
    fpss::Diagnostics d("discrete_grid.yaml");
    const fpss::Procedure p = fpss::parse_procedure(text, "discrete_grid.yaml", d);
    const fpss::Plan plan = fpss::expand(p, b, d);
    benchmark::DoNotOptimize(plan.points);
  }
}
BENCHMARK(BM_ParseAndExpandDiscreteGrid)->Unit(benchmark::kMicrosecond);

}  // namespace
