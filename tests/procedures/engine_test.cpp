// The engine as a library over the real wire: the emulator is the fpss-stand binary forked as a
// child (Modbus TCP on loopback, the sensor on a pty); abort and pause come through RunControl.
#include <gtest/gtest.h>

#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

#include <thread>

#include "calib/samples.h"
#include "drivers/endpoints.h"
#include "stand/session/emulator_process.h"
#include "procedures/engine.h"
#include "procedures/plan.h"
#include "procedures/recorder.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

using test::TempDir;
namespace fs = std::filesystem;

// One emulated bench and both drivers connected to it.
struct Bench {
  explicit Bench(const fs::path& dir, std::vector<std::string> args = {}) {
    EmulatorLaunch l;
    l.exe = test::stand_binary();
    l.args = {"--speed", "20", "--seed", "5"};
    l.args.insert(l.args.end(), args.begin(), args.end());
    l.log = dir / "emulator.log";
    emu = std::make_unique<EmulatorProcess>(l);
    emu->start();
    settings.clock = ClockSync::shared;
    settings.time_scale = 20;
    GimbalOptions go;
    go.endpoint = emu->gimbal_endpoint();
    SensorOptions so;
    so.endpoint = emu->sensor_endpoint();
    gimbal = make_gimbal(go);
    sensor = make_sensor(so);
    gimbal->connect();
    sensor->connect();
  }
  ~Bench() {
    sensor->disconnect();
    gimbal->disconnect();
  }
  EngineSettings settings;
  std::unique_ptr<EmulatorProcess> emu;
  std::unique_ptr<Gimbal> gimbal;
  std::unique_ptr<Sensor> sensor;
};

Plan plan_of(const Procedure& p, const EngineSettings& b) {
  Diagnostics d(p.origin);
  Plan plan = expand(p, b, d);
  EXPECT_TRUE(d.empty()) << d.text();
  return plan;
}

Procedure grid() {
  Diagnostics d("grid.yaml");
  Procedure p = parse_procedure(
      "steps:\n  - home\n  - null_offset_grid: {extent_deg: 0.2, step_deg: 0.05, frames: 4, settle_s: 0.2}\n",
      "grid.yaml", d);
  EXPECT_TRUE(d.empty()) << d.text();
  return p;
}

std::shared_ptr<spdlog::logger> quiet_log() {
  return std::make_shared<spdlog::logger>("test", std::make_shared<spdlog::sinks::null_sink_mt>());
}

TEST(Engine, EmulatorProcessReportsBothEndpoints) {
  TempDir tmp("engine-emu");
  EmulatorLaunch l;
  l.exe = test::stand_binary();
  l.log = tmp / "emu.log";
  EmulatorProcess emu(l);
  EXPECT_FALSE(emu.running());
  emu.start();
  EXPECT_TRUE(emu.running());
  EXPECT_EQ(emu.gimbal_endpoint().rfind("modbus-tcp:127.0.0.1:", 0), 0u) << emu.gimbal_endpoint();
  EXPECT_EQ(emu.sensor_endpoint().rfind("pty:/dev/pts/", 0), 0u) << emu.sensor_endpoint();
  const int status = emu.stop();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;  // SIGTERM: a clean exit 0
  EXPECT_FALSE(emu.running());
  // A bench that cannot start says why.
  EmulatorLaunch bad = l;
  bad.args = {"--bench", (tmp / "missing.yaml").string()};
  EmulatorProcess emu2(bad);
  try {
    emu2.start();
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("exited before it was ready"), std::string::npos) << e.what();
  }
}

TEST(Engine, RunsAPlanAndRecordsEveryPoint) {
  TempDir tmp("engine-run");
  Bench bench(tmp.path());
  const Procedure p = grid();
  const Plan plan = plan_of(p, bench.settings);
  RunRecorder rec(tmp / "run");
  RunControl ctl;
  auto log = quiet_log();
  int done_hooks = 0;
  EngineHooks hooks;
  hooks.point_done = [&](const Action& a, const std::vector<RecordedRow>& rows) {
    ++done_hooks;
    EXPECT_EQ(rows.size(), 4u);
    EXPECT_EQ(rows.front().sample.step, a.point + 1);
  };
  Engine engine(*bench.gimbal, *bench.sensor, bench.settings, plan, rec, *log, ctl, hooks);
  const EngineResult r = engine.run();
  EXPECT_EQ(r.outcome, RunOutcome::completed) << r.reason;
  EXPECT_TRUE(r.safe_state);
  EXPECT_EQ(r.points_done, static_cast<int64_t>(plan.points));
  EXPECT_EQ(done_hooks, static_cast<int>(plan.points));
  EXPECT_EQ(engine.stats().points, static_cast<int64_t>(plan.points));
  const SampleTable t = read_samples_csv(tmp / "run" / "samples.csv");
  EXPECT_EQ(t.size(), plan.points * 4);
  // Each dwell's reference is where the gimbal was, within the in-position tolerance of the target.
  const auto tp = t.numeric_column("target_pitch_arcsec"), ty = t.numeric_column("target_yaw_arcsec");
  for (size_t i = 0; i < t.size(); ++i) {
    EXPECT_NEAR(t.ref_pitch_arcsec[i], tp[i], 1.0);
    EXPECT_NEAR(t.ref_yaw_arcsec[i], ty[i], 1.0);
  }
  // Back at null at the end.
  const GimbalState st = bench.gimbal->read_state();
  EXPECT_NEAR(st.pitch_arcsec, 0, 1.0);
  EXPECT_NEAR(st.yaw_arcsec, 0, 1.0);
}

TEST(Engine, AbortStopsReturnsToNullAndKeepsTheRecording) {
  TempDir tmp("engine-abort");
  Bench bench(tmp.path());
  const Procedure p = grid();
  const Plan plan = plan_of(p, bench.settings);
  RunRecorder rec(tmp / "run");
  RunControl ctl;
  auto log = quiet_log();
  EngineHooks hooks;
  // Abort while the gimbal is away from null: after the first offset point.
  hooks.point_done = [&](const Action& a, const std::vector<RecordedRow>&) {
    if (a.point == 1) {
      ctl.signal = SIGINT;
      ctl.abort = true;
    }
  };
  Engine engine(*bench.gimbal, *bench.sensor, bench.settings, plan, rec, *log, ctl, hooks);
  const EngineResult r = engine.run();
  EXPECT_EQ(r.outcome, RunOutcome::interrupted);
  EXPECT_NE(r.reason.find("signal 2"), std::string::npos) << r.reason;
  EXPECT_TRUE(r.safe_state);
  EXPECT_EQ(r.points_done, 2);
  const GimbalState st = bench.gimbal->read_state();
  EXPECT_NEAR(st.pitch_arcsec, 0, 1.0);
  EXPECT_NEAR(st.yaw_arcsec, 0, 1.0);
  EXPECT_FALSE(st.has(kMoving));
  EXPECT_EQ(read_samples_csv(tmp / "run" / "samples.csv").size(), 8u);

  // The same recorder folder picks up where it stopped: no point twice, none lost.
  ctl.abort = false;
  hooks.point_done = nullptr;
  RunRecorder rec2(tmp / "run");
  EXPECT_EQ(rec2.next_point(), 2);
  Engine again(*bench.gimbal, *bench.sensor, bench.settings, plan, rec2, *log, ctl, hooks);
  const EngineResult r2 = again.run(2);
  EXPECT_EQ(r2.outcome, RunOutcome::completed) << r2.reason;
  EXPECT_EQ(again.stats().points, static_cast<int64_t>(plan.points) - 2);
  const SampleTable t = read_samples_csv(tmp / "run" / "samples.csv");
  EXPECT_EQ(t.size(), plan.points * 4);
  for (size_t i = 1; i < t.size(); ++i) EXPECT_TRUE(t.step[i] == t.step[i - 1] || t.step[i] == t.step[i - 1] + 1);
}

TEST(Engine, PauseHoldsBetweenPoints) {
  TempDir tmp("engine-pause");
  Bench bench(tmp.path());
  const Procedure p = grid();
  const Plan plan = plan_of(p, bench.settings);
  RunRecorder rec(tmp / "run");
  RunControl ctl;
  auto log = quiet_log();
  std::atomic<int64_t> done{0};
  std::atomic<int64_t> done_while_paused{-1};
  EngineHooks hooks;
  std::thread releaser;
  hooks.point_done = [&](const Action& a, const std::vector<RecordedRow>&) {
    done = a.point + 1;
    if (a.point == 2) {
      ctl.pause = true;
      releaser = std::thread([&] {
        // Whatever the scheduler does, no point may complete while the pause holds.
        std::this_thread::sleep_for(std::chrono::milliseconds(400));
        done_while_paused = done.load();
        ctl.pause = false;
      });
    }
  };
  Engine engine(*bench.gimbal, *bench.sensor, bench.settings, plan, rec, *log, ctl, hooks);
  const EngineResult r = engine.run();
  if (releaser.joinable()) releaser.join();
  EXPECT_EQ(r.outcome, RunOutcome::completed) << r.reason;
  EXPECT_EQ(done_while_paused.load(), 3);
  EXPECT_EQ(r.points_done, static_cast<int64_t>(plan.points));
}

TEST(Engine, FollowingErrorIsClearedAndThePointMeasuredAgain) {
  TempDir tmp("engine-fe");
  // The fault fires at the 40th Modbus request: in the middle of the grid.
  Bench bench(tmp.path(), {"--fault", "following_error:at_request=40"});
  const Procedure p = grid();
  const Plan plan = plan_of(p, bench.settings);
  RunRecorder rec(tmp / "run");
  RunControl ctl;
  auto log = quiet_log();
  Engine engine(*bench.gimbal, *bench.sensor, bench.settings, plan, rec, *log, ctl);
  const EngineResult r = engine.run();
  EXPECT_EQ(r.outcome, RunOutcome::completed) << r.reason;
  EXPECT_GE(engine.stats().remeasured, 1);
  EXPECT_GE(engine.stats().recoveries, 1);
  const auto journal = RunRecorder::read_journal(tmp / "run" / "points.jsonl");
  ASSERT_EQ(journal.size(), plan.points);
  int retried = 0;
  for (const auto& j : journal) retried += j.attempts > 1;
  EXPECT_EQ(retried, 1);
}

}  // namespace
}  // namespace fpss
