// The engine's test bench: both in-process fake devices on one simulated bench, a grid's plan, and a
// run folder's recorder on the event stream (no binary, no wire).
#pragma once
#include <gtest/gtest.h>
#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

#include <functional>
#include <memory>
#include <string>

#include "procedures/engine.h"
#include "procedures/plan.h"
#include "procedures/recorder.h"
#include "tests/support/fake_devices.h"
#include "tests/support/test_support.h"

namespace fpss::test {

inline Plan plan_of(const Procedure& p, const EngineSettings& b) {
  Diagnostics d(p.origin);
  Plan plan = expand(p, b, d);
  EXPECT_TRUE(d.empty()) << d.text();
  return plan;
}

inline Procedure grid(const std::string& extra = {}) {
  Diagnostics d("grid.yaml");
  Procedure p = parse_procedure(
      "steps:\n  - home\n  - null_offset_grid: {extent_deg: 0.2, step_deg: 0.05, frames: 4, settle_s: 0.2" + extra + "}\n",
      "grid.yaml", d);
  EXPECT_TRUE(d.empty()) << d.text();
  return p;
}

inline std::shared_ptr<spdlog::logger> quiet_log() {
  return std::make_shared<spdlog::logger>("test", std::make_shared<spdlog::sinks::null_sink_mt>());
}

// One simulated bench and both fake devices on it, the grid's plan, the event stream a run
// publishes to with a recorder of `run_dir` subscribed, and the operator's controls.
struct Bench {
  explicit Bench(const std::filesystem::path& run_dir, const std::string& grid_extra = {}) {
    settings.clock = ClockSync::shared;
    settings.time_scale = 20;
    gimbal.connect();
    sensor.connect();
    plan = plan_of(grid(grid_extra), settings);
    recorder = std::make_unique<RunRecorder>(run_dir);
    record_with(bus, *recorder);
  }
  // Calls `f(point_done)` for every PointDone.
  void on_point_done(std::function<void(const PointDone&)> f) {
    bus.subscribe([f](const Event& e) {
      if (const auto* p = std::get_if<PointDone>(&e)) f(*p);
    });
  }
  std::unique_ptr<Engine> engine(ResumePoint from = {}) {
    return std::make_unique<Engine>(gimbal, sensor, settings, plan, bus, *log, ctl, hooks, from);
  }
  EngineSettings settings;
  test::FakeBench fake{default_bench_config(), 20};
  test::FakeGimbal gimbal{fake};
  test::FakeSensor sensor{fake};
  EventBus bus;
  Plan plan;
  std::unique_ptr<RunRecorder> recorder;
  RunControl ctl;
  EngineHooks hooks;
  std::shared_ptr<spdlog::logger> log = quiet_log();
};

}  // namespace fpss::test
