// `fpss-stand run` end to end over the real wire (the binary forks the emulator) when things go
// wrong: it survives SIGKILL (resume), SIGTERM, device faults and bad input.
#include <fmt/format.h>

#include <cstring>

#include "tests/stand/run_helpers.h"

namespace fpss {
namespace {

using namespace runtest;
using test::run_stand;
using test::TempDir;

TEST(Run, SigkillThenResumeGivesTheSamePoints) {
  TempDir tmp("run-resume");
  test::write_file(tmp / "grid.yaml",
                   "name: resume_grid\nsteps:\n  - home\n"
                   "  - null_offset_grid: {extent_deg: 0.3, step_deg: 0.05, frames: 8, settle_s: 0.3}\n"
                   "  - calibrate: {}\n");
  const std::vector<std::string> common{"--emulate", "--seed", "11", "--speed", "20", "--quiet"};
  // Uninterrupted.
  const auto runs_a = tmp / "a";
  std::vector<std::string> args_a{"run", (tmp / "grid.yaml").string(), "--runs-dir", runs_a.string()};
  args_a.insert(args_a.end(), common.begin(), common.end());
  ASSERT_EQ(run_stand(args_a, tmp.path(), "a").code, 0);
  // Killed mid-procedure, no chance to clean up.
  const auto runs_b = tmp / "b";
  std::vector<std::string> args_b{"run", (tmp / "grid.yaml").string(), "--runs-dir", runs_b.string()};
  args_b.insert(args_b.end(), common.begin(), common.end());
  {
    test::Child c = test::start_stand(args_b, tmp.path(), "b");
    ASSERT_TRUE(
        test::wait_until([&] { return test::journaled_points(runs_b) >= 9; }, 60, std::chrono::milliseconds(20)));
    c.signal(SIGKILL);
    EXPECT_EQ(c.wait(180), 128 + SIGKILL);
  }
  const fs::path run_b = only_run(runs_b);
  EXPECT_EQ(run_json(run_b)["outcome"], "running");  // nobody lived to say otherwise
  const size_t done_before = RunRecorder::read_journal(run_b / "points.jsonl").size();
  ASSERT_GE(done_before, 9u);
  ASSERT_LT(done_before, 49u);
  // The bench the killed run started dies with it (PDEATHSIG); resume starts a new one.
  const auto rr = run_stand({"run", "--resume", run_b.string(), "--quiet"}, tmp.path(), "resume");
  ASSERT_EQ(rr.code, 0) << rr.out << rr.err;

  const SampleTable a = read_samples_csv(only_run(runs_a) / "samples.csv");
  const SampleTable b = read_samples_csv(run_b / "samples.csv");
  expect_contiguous_points(a, 49);
  expect_contiguous_points(b, 49);
  const auto pa = points_of(a), pb = points_of(b);
  ASSERT_EQ(pa.size(), pb.size());
  for (const auto& [step, p] : pa) {
    const auto& q = pb.at(step);
    EXPECT_EQ(p.phase, q.phase) << step;
    EXPECT_EQ(p.target_pitch, q.target_pitch) << step;
    EXPECT_EQ(p.target_yaw, q.target_yaw) << step;
    EXPECT_EQ(p.rows, q.rows) << step;
    // Same seed, same point: the same counts within the sensor noise (0.3 counts, 8 frames).
    EXPECT_NEAR(p.mean_alpha, q.mean_alpha, 1.0) << step;
    EXPECT_NEAR(p.mean_beta, q.mean_beta, 1.0) << step;
  }
  const auto sess = b.numeric_column("session");
  EXPECT_EQ(sess.front(), 1);
  EXPECT_EQ(sess.back(), 2);
  const auto doc = run_json(run_b);
  EXPECT_EQ(doc["outcome"], "completed");
  ASSERT_EQ(doc["sessions"].size(), 2u);
  EXPECT_EQ(doc["sessions"][1]["first_point"], done_before + 1);  // 1-based, as everywhere
  EXPECT_TRUE(fs::exists(run_b / "calibration.json"));
  // A completed run cannot be resumed again.
  EXPECT_EQ(run_stand({"run", "--resume", run_b.string(), "--quiet"}, tmp.path(), "again").code, 2);
}

TEST(Run, SigtermAndSigintStopSafelyAndMarkTheRunInterrupted) {
  for (const int sig : {SIGTERM, SIGINT}) {
    SCOPED_TRACE(strsignal(sig));
    TempDir tmp("run-signal");
    const auto runs = tmp / "runs";
    test::Child c = test::start_stand(
        {"run", proc("discrete_grid.yaml"), "--emulate", "--runs-dir", runs.string(), "--quiet"}, tmp.path());
    ASSERT_TRUE(
        test::wait_until([&] { return test::journaled_points(runs) >= 5; }, 60, std::chrono::milliseconds(20)));
    c.signal(sig);
    EXPECT_EQ(c.wait(60), 1);
    const fs::path run = only_run(runs);
    const auto doc = run_json(run);
    EXPECT_EQ(doc["outcome"], "interrupted");
    EXPECT_NE(doc["reason"].get<std::string>().find(fmt::format("signal {}", sig)), std::string::npos);
    EXPECT_TRUE(doc["safe_state"].get<bool>());
    EXPECT_TRUE(doc.contains("ended_utc"));
    const std::string events = test::read_file(run / "events.log");
    EXPECT_NE(events.find("gimbal back at null"), std::string::npos) << events;
    // The recording up to the interruption is whole.
    const SampleTable t = read_samples_csv(run / "samples.csv");
    expect_contiguous_points(t, static_cast<int64_t>(RunRecorder::read_journal(run / "points.jsonl").size()));
    SqliteCatalogue cat(runs / "stand.db", Catalogue::Mode::read_only);
    EXPECT_EQ(cat.find_run(run_id_of(run))->outcome, RunOutcome::interrupted);
  }
}

TEST(Run, DeviceFaultsAreRecovered) {
  TempDir tmp("run-faults");
  test::write_file(tmp / "grid.yaml",
                   "name: fault_grid\nsteps:\n  - home\n"
                   "  - null_offset_grid: {extent_deg: 0.24, step_deg: 0.06, frames: 5, settle_s: 0.3}\n");
  const auto runs = tmp / "runs";
  // Dropped Modbus connection, a reply past the timeout, garbage and bad CRCs on the line, a
  // following error, a sensor that stops streaming and one that goes silent.
  const auto r = run_stand({"run", (tmp / "grid.yaml").string(), "--emulate", "--runs-dir", runs.string(), "--quiet",
                            "--fault", "modbus_drop:count=1,at_s=3", "--fault", "sensor_garbage:bytes=300,at_s=6",
                            "--fault", "sensor_bad_crc:frames=10,at_s=9", "--fault", "following_error:at_s=12",
                            "--fault", "sensor_stop:at_s=16", "--fault", "sensor_silence:duration_s=2,at_s=22",
                            "--fault", "modbus_delay:delay_s=2,count=1,at_s=28"},
                           tmp.path());
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const fs::path run = only_run(runs);
  const auto doc = run_json(run);
  EXPECT_EQ(doc["outcome"], "completed");
  const auto& s = doc["sessions"][0];
  EXPECT_GE(s["engine"]["remeasured"].get<int>(), 2) << s.dump();  // the following error and the silent sensor
  EXPECT_GE(s["sensor_stats"]["crc_errors"].get<int>(), 10) << s.dump();
  EXPECT_GT(s["sensor_stats"]["garbage_bytes"].get<int>(), 0) << s.dump();
  const std::string events = test::read_file(run / "events.log");
  EXPECT_NE(events.find("following_error"), std::string::npos);
  EXPECT_NE(events.find("reconnected"), std::string::npos);  // the driver's own retry, in the run's log
  const SampleTable t = read_samples_csv(run / "samples.csv");
  expect_contiguous_points(t, 33);
  for (size_t i = 0; i < t.size(); ++i) ASSERT_EQ(t.extra_column("sensor_status")[i], "7");  // only valid frames
}

TEST(Run, AnUnrecoverableFaultStopsSafelyWithTheReason) {
  TempDir tmp("run-fatal");
  test::write_file(tmp / "grid.yaml",
                   "steps:\n  - home\n"
                   "  - null_offset_grid: {extent_deg: 0.24, step_deg: 0.06, frames: 5, settle_s: 0.3}\n");
  test::write_file(tmp / "stand.yaml",
                   "gimbal: {endpoint: 'modbus-tcp:127.0.0.1:1'}\n"
                   "sensor: {endpoint: 'pty:/dev/null', frame_timeout_s: 0.3, command_timeout_s: 0.2, "
                   "command_retries: 0}\n"
                   "points: {max_remeasure: 1}\n");
  const auto runs = tmp / "runs";
  const auto r = run_stand({"run", (tmp / "grid.yaml").string(), "--emulate", "--stand", (tmp / "stand.yaml").string(),
                            "--runs-dir", runs.string(), "--fault", "sensor_silence:duration_s=100000,at_s=6"},
                           tmp.path());
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  const fs::path run = only_run(runs);
  const auto doc = run_json(run);
  EXPECT_EQ(doc["outcome"], "failed");
  EXPECT_NE(doc["reason"].get<std::string>().find("failed after 2 attempts: the sensor sent no frame"),
            std::string::npos)
      << doc["reason"];
  EXPECT_TRUE(doc["safe_state"].get<bool>());  // the gimbal still answers: it went back to null
  EXPECT_NE(r.err.find("failed after 2 attempts"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("resume with: fpss-stand run --resume"), std::string::npos) << r.out;
  // Everything measured before the fault is there and whole.
  const auto journal = RunRecorder::read_journal(run / "points.jsonl");
  ASSERT_GT(journal.size(), 0u);
  ASSERT_LT(journal.size(), 33u);
  expect_contiguous_points(read_samples_csv(run / "samples.csv"), static_cast<int64_t>(journal.size()));
}

TEST(Run, BadProceduresAndStandFilesExit2AndMoveNothing) {
  TempDir tmp("run-bad");
  const auto runs = tmp / "runs";
  test::write_file(tmp / "bad.yaml",
                   "steps:\n"                                  // 1
                   "  - home\n"                                // 2
                   "  - spin: {rate_deg_s: 1}\n"               // 3 unknown step
                   "  - settle: {}\n"                          // 4 missing field
                   "  - move: {pitch_deg: 1.5}\n"              // 5 out of limits (+-0.75 deg)
                   "  - sample: {frames: many}\n");            // 6 wrong type
  // Unknown step, missing field, wrong type: found by parsing.
  auto r = run_stand({"run", (tmp / "bad.yaml").string(), "--emulate", "--runs-dir", runs.string()}, tmp.path());
  EXPECT_EQ(r.code, 2) << r.err;
  const std::string f = (tmp / "bad.yaml").string();
  EXPECT_NE(r.err.find(f + ":3:5: step 2: unknown step \"spin\""), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(f + ":4:13: step 3 (settle): missing field duration_s"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(f + ":6:22: step 5 (sample): field frames: expected an integer, got \"many\""),
            std::string::npos)
      << r.err;
  // ... and in the same pass the valid steps are checked against the stand's soft limits.
  EXPECT_NE(r.err.find(f + ":5:5: step 4 (move): target out of soft limits: pitch +1.5000 deg"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("4 errors:"), std::string::npos) << r.err;
  // Out of limits: found by expanding against the stand once the file parses.
  test::write_file(tmp / "far.yaml", "steps:\n  - home\n  - move: {pitch_deg: 1.5}\n  - sample: {frames: 2}\n");
  r = run_stand({"run", (tmp / "far.yaml").string(), "--emulate", "--runs-dir", runs.string()}, tmp.path());
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find((tmp / "far.yaml").string() + ":3:5: step 2 (move): target out of soft limits: pitch +1.5000 deg"),
            std::string::npos)
      << r.err;
  // A bad stand file, reported together with the procedure's errors.
  test::write_file(tmp / "stand.yaml", "gimbal: {endpoint: 'modbus-tcp:localhost'}\nsensor: {endpoint: 'pty:/x'}\n"
                                       "axes: {pitch: alpha, yaw: alpha}\n");
  r = run_stand({"run", (tmp / "bad.yaml").string(), "--stand", (tmp / "stand.yaml").string(), "--runs-dir",
                 runs.string()},
                tmp.path());
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find((tmp / "stand.yaml").string() + ":1:20: gimbal: field endpoint:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find((tmp / "stand.yaml").string() + ":3:7: axes: pitch and yaw both map to alpha"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find(f + ":3:5:"), std::string::npos) << r.err;
  // A sensor that is not the unit the stand file names: stopped before anything moves.
  test::write_file(tmp / "unit.yaml", "unit: FPSS2-SN007\ngimbal: {endpoint: 'modbus-tcp:127.0.0.1:1'}\n"
                                      "sensor: {endpoint: 'pty:/dev/null'}\n");
  r = run_stand({"run", proc("discrete_grid.yaml"), "--emulate", "--stand", (tmp / "unit.yaml").string(),
                 "--runs-dir", runs.string()},
                tmp.path());
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("the sensor reports serial \"EMU-0001\""), std::string::npos) << r.err;
  // Usage errors.
  EXPECT_EQ(run_stand({"run", proc("discrete_grid.yaml"), "--runs-dir", runs.string()}, tmp.path()).code, 2);
  EXPECT_EQ(run_stand({"run", proc("discrete_grid.yaml"), "--stand", (tmp / "stand.yaml").string(), "--seed", "3"},
                      tmp.path())
                .code,
            2);
  EXPECT_EQ(run_stand({"run", "--resume", tmp.path().string()}, tmp.path()).code, 2);
  // Nothing was recorded, so nothing moved: every error came before the bench was touched.
  EXPECT_TRUE(test::run_dirs(runs).empty());
}

TEST(Run, DryRunPrintsThePlanAndMovesNothing) {
  TempDir tmp("run-dry");
  const auto runs = tmp / "runs";
  const auto r = run_stand({"run", proc("discrete_grid.yaml"), "--emulate", "--dry-run", "--runs-dir", runs.string()},
                           tmp.path());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("points: 113 (57 null, 56 offset, 0 slew segments)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("estimated duration:"), std::string::npos);
  EXPECT_NE(r.out.find("point  113 null"), std::string::npos);
  EXPECT_NE(r.out.find("all targets inside the soft limits"), std::string::npos);
  EXPECT_FALSE(fs::exists(runs));
  // A stand with tighter limits: the same procedure no longer fits.
  test::write_file(tmp / "stand.yaml", "gimbal: {endpoint: 'modbus-tcp:10.0.0.1:502'}\nsensor: {endpoint: 'serial:/dev/ttyS9'}\n"
                                       "soft_limits: {pitch_deg: [-0.3, 0.3], yaw_deg: [-0.5, 0.5]}\n");
  const auto r2 = run_stand({"run", proc("discrete_grid.yaml"), "--stand", (tmp / "stand.yaml").string(), "--dry-run"},
                            tmp.path());
  EXPECT_EQ(r2.code, 2);
  EXPECT_NE(r2.err.find("discrete_grid.yaml:9:5: step 2 (null_offset_grid): target out of soft limits: pitch +0.3300 deg"),
            std::string::npos)
      << r2.err;
}

}  // namespace
}  // namespace fpss
