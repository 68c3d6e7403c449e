// The active sim-to-real loop end to end: diagnose over several recordings, design a follow-up
// from GAP.json, investigate on the emulated bench (Modbus TCP and a pty per run) into
// INVESTIGATION.json and the catalogue; and the confusable cases in-process.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <cstdio>
#include <map>
#include <optional>
#include <sstream>
#include <vector>
#include <string>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "fixtures/bench.h"
#include "stand/investigate/confusable.h"
#include "stand/investigate/followup_design.h"
#include "stand/investigate/investigation.h"
#include "tests/procedures/run_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {
namespace fs = std::filesystem;
using test::run_stand;
using test::TempDir;
using testing::HasSubstr;
using testing::Not;

const std::string kModel = (test::source_dir() / "calib/data/published/a-6-fpss1.json").string();

// A dwells-only grid and, separately, its follow-up with slews, both with a 4 ms sensor latency.
void simulate(const TempDir& tmp) {
  test::write_file(tmp / "skew.yaml", "effects:\n  - {name: time_skew, skew_s: 0.004}\n");
  ASSERT_EQ(run_stand({"simulate", "--out", (tmp / "dwells.csv").string(), "--bench", (tmp / "skew.yaml").string(),
                       "--samples-per-dwell", "25", "--seed", "5"},
                      tmp.path()).code, 0);
}

TEST(Investigate, ADesignFromADwellsOnlyDiagnosisAddsSlewsAndTheJointDiagnosisNamesTheSkew) {
  TempDir tmp("investigate-design");
  simulate(tmp);
  auto r = run_stand({"diagnose", "--model", kModel, "--data", (tmp / "dwells.csv").string(), "--out",
                      (tmp / "gap.json").string(), "--partial"},
                     tmp.path());
  ASSERT_EQ(r.code, 0) << r.err;
  auto gap = nlohmann::json::parse(test::read_file(tmp / "gap.json"));
  EXPECT_NE(gap["cause"], "time_skew");
  ASSERT_TRUE(gap.contains("candidates"));
  for (const auto& c : gap["candidates"]) {
    if (c["name"] == "time_skew") {
      EXPECT_EQ(c["status"], "unbounded") << c.dump();
    }
  }
  // Within a budget nothing fits in: exit 1, no file.
  r = run_stand({"design", "--observe", (tmp / "gap.json").string(), "--emulate", "--out",
                 (tmp / "none.yaml").string(), "--max-bench-s", "2"},
                tmp.path());
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_FALSE(fs::exists(tmp / "none.yaml"));
  // Within the default budget (half the recording's bench time): slews, at most that long.
  r = run_stand({"design", "--discriminate", (tmp / "gap.json").string(), "--observe", (tmp / "gap.json").string(),
                 "--emulate", "--bench", (tmp / "skew.yaml").string(), "--out", (tmp / "followup.yaml").string(),
                 "--json"},
                tmp.path());
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const auto design = nlohmann::json::parse(r.out);
  EXPECT_LE(design["bench_s"].get<double>(), design["budget_s"].get<double>());
  EXPECT_NEAR(design["budget_s"].get<double>(), 0.5 * design["first_bench_s"].get<double>(), 1e-9);
  const std::string text = test::read_file(tmp / "followup.yaml");
  EXPECT_THAT(text, HasSubstr("continuous_slew"));
  bool skew_planned = false;
  for (const auto& b : design["bounds"]) skew_planned = skew_planned || b["name"] == "time_skew";
  EXPECT_TRUE(skew_planned) << design.dump(1);
  // The follow-up run (in-process on the same bench), then both recordings jointly.
  ASSERT_EQ(run_stand({"simulate", "--procedure", (tmp / "followup.yaml").string(), "--bench",
                       (tmp / "skew.yaml").string(), "--seed", "6", "--out", (tmp / "followup.csv").string()},
                      tmp.path()).code, 0);
  r = run_stand({"diagnose", "--model", kModel, "--data", (tmp / "dwells.csv").string(), "--data",
                 (tmp / "followup.csv").string(), "--out", (tmp / "joint.json").string(), "--partial"},
                tmp.path());
  ASSERT_EQ(r.code, 0) << r.err;
  gap = nlohmann::json::parse(test::read_file(tmp / "joint.json"));
  EXPECT_EQ(gap["cause"], "time_skew") << gap.dump(1);
  EXPECT_NEAR(gap["causes"][0]["params"]["skew_s"].get<double>(), 0.004, 0.0004);
  ASSERT_EQ(gap["recordings"].size(), 2u);
  EXPECT_THAT(gap["recordings"][1]["source"].get<std::string>(), HasSubstr("followup.csv"));
}

// A bench file (aged.yaml) whose sensor is the model's transfer function aged a little: each
// sinusoid 5 % in amplitude and 0.05 rad in phase (aged.json).
void write_aged_bench(const TempDir& tmp) {
  auto aged = nlohmann::json::parse(test::read_file(kModel));
  for (const char* axis : {"alpha", "beta"}) {
    aged[axis][2] = aged[axis][2].get<double>() * 1.05;
    aged[axis][4] = aged[axis][4].get<double>() + 0.05;
    aged[axis][5] = aged[axis][5].get<double>() * 0.95;
    aged[axis][7] = aged[axis][7].get<double>() - 0.05;
  }
  test::write_file(tmp / "aged.json", aged.dump());
  test::write_file(tmp / "aged.yaml", "effects:\n  - {name: coefficients, file: aged.json}\n");
}

TEST(Investigate, ANarrowGridsBiasAndScaleAgainstAnAgedTransferFunctionIsSettledByOffsetsAcrossTheRange) {
  TempDir tmp("investigate-coefficients");
  write_aged_bench(tmp);
  ASSERT_EQ(run_stand({"simulate", "--out", (tmp / "narrow.csv").string(), "--bench", (tmp / "aged.yaml").string(),
                       "--extent-deg", "0.05", "--step-deg", "0.01", "--samples-per-dwell", "25", "--seed", "7"},
                      tmp.path()).code, 0);
  auto r = run_stand({"diagnose", "--model", kModel, "--data", (tmp / "narrow.csv").string(), "--out",
                      (tmp / "gap.json").string(), "--partial"},
                     tmp.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto gap = nlohmann::json::parse(test::read_file(tmp / "gap.json"));
  EXPECT_NE(gap["cause"], "coefficients");
  ASSERT_FALSE(gap["ambiguous"].empty()) << gap.dump(1);
  EXPECT_EQ(gap["ambiguous"][0]["separated_by"]["factor"], "angle");
  // GAP.json's own prediction for the set: separated, by a plan over the range.
  EXPECT_EQ(gap["ambiguous"][0]["best_followup"]["separates"], true) << gap["ambiguous"][0].dump(1);

  r = run_stand({"design", "--discriminate", (tmp / "gap.json").string(), "--emulate", "--out",
                 (tmp / "followup.yaml").string(), "--json"},
                tmp.path());
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const auto design = nlohmann::json::parse(r.out);
  ASSERT_EQ(design["pairs"].size(), 1u) << design.dump(1);
  EXPECT_EQ(design["pairs"][0]["a"], "coefficients");
  EXPECT_THAT(design["pairs"][0]["b"].get<std::string>(), HasSubstr("bias"));
  EXPECT_EQ(design["pairs"][0]["separated"], true);
  EXPECT_EQ(design["range"]["asked"], true);
  EXPECT_EQ(design["range"]["measured"], true);
  EXPECT_LE(design["bench_s"].get<double>(), design["budget_s"].get<double>());

  // The follow-up on the same bench, then both jointly: the change of coefficients, measured over the range.
  ASSERT_EQ(run_stand({"simulate", "--procedure", (tmp / "followup.yaml").string(), "--bench",
                       (tmp / "aged.yaml").string(), "--seed", "8", "--out", (tmp / "followup.csv").string()},
                      tmp.path()).code, 0);
  r = run_stand({"diagnose", "--model", kModel, "--data", (tmp / "narrow.csv").string(), "--data",
                 (tmp / "followup.csv").string(), "--out", (tmp / "joint.json").string(), "--partial"},
                tmp.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto joint = nlohmann::json::parse(test::read_file(tmp / "joint.json"));
  EXPECT_EQ(joint["cause"], "coefficients") << joint["causes"].dump();
  for (const auto& c : joint["candidates"]) {
    if (c["name"] == "coefficients") {
      EXPECT_EQ(c["status"], "named") << c.dump();
    }
  }
}

TEST(Investigate, AFollowUpStaysWithinTheCalibratedRangeTheDiagnosisWasGiven) {
  TempDir tmp("investigate-range");
  simulate(tmp);
  auto r = run_stand({"diagnose", "--model", kModel, "--data", (tmp / "dwells.csv").string(), "--out",
                      (tmp / "gap.json").string(), "--partial", "--calibrated-range-arcsec", "800"},
                     tmp.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto gap = nlohmann::json::parse(test::read_file(tmp / "gap.json"));
  EXPECT_EQ(gap["calibrated_range_arcsec"], 800.0);
  r = run_stand({"design", "--observe", (tmp / "gap.json").string(), "--emulate", "--out",
                 (tmp / "followup.yaml").string(), "--max-bench-s", "200"},
                tmp.path());
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  // Every angle the follow-up names lies within the range (an approach starts 300 arcsec outside
  // its point, which lies 300 inside the range's end).
  std::istringstream yaml(test::read_file(tmp / "followup.yaml"));
  double largest = 0;
  for (std::string line; std::getline(yaml, line);) {
    if (line.rfind('#', 0) == 0) continue;
    for (const char* key : {"pitch_arcsec: ", "yaw_arcsec: ", "amplitude_arcsec: ", "extent_arcsec: "}) {
      const auto at = line.find(key);
      if (at != std::string::npos) largest = std::max(largest, std::abs(std::stod(line.substr(at + std::strlen(key)))));
    }
  }
  EXPECT_GT(largest, 0.0);
  EXPECT_LE(largest, 800.0);
  // Out of range: exit 2, naming the option.
  r = run_stand({"diagnose", "--model", kModel, "--data", (tmp / "dwells.csv").string(), "--out",
                 (tmp / "bad.json").string(), "--partial", "--calibrated-range-arcsec", "10"},
                tmp.path());
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr("calibrated-range-arcsec"));
}

TEST(Investigate, ARunRecordsTheSideOfEveryApproachThroughUnrecordedMoves) {
  TempDir tmp("approach-sides");
  test::write_file(tmp / "p.yaml",
                   "steps:\n  - home\n"
                   "  - move: {pitch_arcsec: -300, yaw_arcsec: 200}\n  - move: {pitch_arcsec: 0, yaw_arcsec: 0}\n"
                   "  - sample: {frames: 5}\n"
                   "  - move: {pitch_arcsec: 300, yaw_arcsec: 0}\n  - move: {pitch_arcsec: 0, yaw_arcsec: 0}\n"
                   "  - sample: {frames: 5}\n");
  const auto r = run_stand({"run", (tmp / "p.yaml").string(), "--emulate", "--speed", "20", "--runs-dir",
                            (tmp / "runs").string(), "--no-progress", "--quiet"},
                           tmp.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto dirs = test::run_dirs(tmp / "runs");
  ASSERT_EQ(dirs.size(), 1u);
  const std::string csv = test::read_file(dirs.front() / "samples.csv");
  const auto header = csv.substr(0, csv.find('\n'));
  ASSERT_THAT(header, HasSubstr("approach_pitch,approach_yaw"));
  // The emulator's mount is the identity: pitch came up then down, yaw down then stood still.
  std::istringstream lines(csv);
  std::string line;
  std::getline(lines, line);
  std::map<std::string, std::string> side_of_step;
  while (std::getline(lines, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    side_of_step[f[2]] = f[f.size() - 2] + "," + f.back();
  }
  EXPECT_EQ(side_of_step["1"], "1,-1");
  EXPECT_EQ(side_of_step["2"], "-1,0");
}

TEST(Investigate, OnTheEmulatedBenchTheLoopRunsFollowUpsIntoTheCatalogueAndWritesItsRecord) {
  TempDir tmp("investigate-emulated");
  const fs::path runs = tmp / "runs", out = tmp / "inv";
  const auto r = run_stand({"investigate", "--model", kModel, "--emulate", "--effect", "time_skew:skew_s=0.004",
                            "--procedure", (test::source_dir() / "procedures/discrete_grid.yaml").string(), "--speed",
                            "20", "--runs-dir", runs.string(), "--out", out.string(), "--quiet", "--max-runs", "2"},
                           tmp.path(), "investigate", 600);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const auto inv = nlohmann::json::parse(test::read_file(out / "INVESTIGATION.json"));
  ASSERT_EQ(inv["runs"].size(), 2u) << inv.dump(1);
  ASSERT_EQ(inv["steps"].size(), 2u);
  EXPECT_EQ(inv["steps"][0]["why"], "the first run");
  EXPECT_THAT(inv["steps"][1]["why"].get<std::string>(), HasSubstr("time_skew"));
  // Both runs on the one emulated bench the investigation started: the second starts on its clock
  // after the first ended, and the joint diagnosis ran on that clock.
  ASSERT_EQ(inv["recordings"].size(), 2u);
  EXPECT_EQ(inv["recordings"][1]["clock"], "bench");
  EXPECT_GT(inv["recordings"][1]["time_span_s"][0].get<double>(), inv["recordings"][0]["time_span_s"][1].get<double>());
  EXPECT_EQ(nlohmann::json::parse(test::read_file(fs::path(inv["runs"][1].get<std::string>()) / "run.json"))["sessions"][0]
                ["emulator"]["shared"],
            true);
  // The final joint diagnosis in GAP.json's fields, at the top level.
  for (const char* key : {"verdict", "cause", "causes", "effects", "ambiguous"}) EXPECT_TRUE(inv.contains(key)) << key;
  EXPECT_EQ(inv["cause"], "time_skew") << inv.dump(1);
  EXPECT_NEAR(inv["causes"][0]["params"]["skew_s"].get<double>(), 0.004, 0.0004);
  EXPECT_LE(inv["bench_time_s"]["followups_ratio"].get<double>(), 1.0);
  EXPECT_TRUE(fs::exists(out / "FOLLOWUP-1.yaml"));
  EXPECT_THAT(test::read_file(out / "INVESTIGATION.html"), HasSubstr("time_skew"));
  // Both runs are run folders of the stand, in the catalogue.
  for (const auto& run : inv["runs"]) EXPECT_TRUE(fs::exists(fs::path(run.get<std::string>()) / "run.json")) << run;
  const auto listed = run_stand({"runs", "--catalogue", (runs / "stand.db").string()}, tmp.path());
  ASSERT_EQ(listed.code, 0) << listed.err;
  EXPECT_THAT(listed.out, HasSubstr("FOLLOWUP-1"));
}

// The confident wrong answer: a dwells-only grid on a bench whose temperature follows a
// slow sine read as a drift. On one emulated bench, whose clock and temperature go on between
// runs, the investigation tells the two apart either way round.
TEST(Investigate, OnTheEmulatedBenchANarrowGridsLookAlikeOfAnAgedTransferFunctionEndsMeasuredOverTheRange) {
  TempDir tmp("investigate-emulated-coefficients");
  write_aged_bench(tmp);
  test::write_file(tmp / "narrow.yaml", "name: narrow_grid\nsteps:\n  - home\n  - null_offset_grid: {axes: [pitch, "
                                        "yaw], extent_deg: 0.05, step_deg: 0.01, frames: 25, settle_s: 0.2}\n");
  const fs::path out = tmp / "inv";
  const auto r = run_stand({"investigate", "--model", kModel, "--emulate", "--bench", (tmp / "aged.yaml").string(),
                            "--procedure", (tmp / "narrow.yaml").string(), "--speed", "20", "--runs-dir",
                            (tmp / "runs").string(), "--out", out.string(), "--quiet"},
                           tmp.path(), "investigate", 600);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const auto inv = nlohmann::json::parse(test::read_file(out / "INVESTIGATION.json"));
  // The first run: a look-alike of the refit (a bias, or a bias and a scale), the refit beside it.
  const auto& first = inv["steps"][0]["diagnosis"];
  EXPECT_NE(first["cause"], "coefficients");
  bool beside = false;
  for (const auto& set : first["ambiguous"]) {
    for (const auto& m : set) beside = beside || m == "coefficients";
  }
  EXPECT_TRUE(beside) << first.dump(1);
  // The end: the change of coefficients, named and measured over the range, within the budget.
  EXPECT_EQ(inv["cause"], "coefficients") << inv["causes"].dump();
  for (const auto& c : inv["candidates"]) {
    if (c["name"] == "coefficients") {
      EXPECT_EQ(c["status"], "named") << c.dump();
    }
  }
  EXPECT_LE(inv["bench_time_s"]["followups_ratio"].get<double>(), 1.0);
}

TEST(Investigate, OnOneEmulatedBenchADriftAndATemperatureSineAreToldApart) {
  TempDir tmp("investigate-drift-temperature");
  const std::map<std::string, std::string> truths = {
      {"temperature", "{name: temperature, pitch_arcsec_per_c: 1.0, yaw_arcsec_per_c: 1.0}"},
      {"drift", "{name: drift, pitch_arcsec_per_s: 0.002, yaw_arcsec_per_s: 0.002}"}};
  for (const auto& [cause, effect] : truths) {
    SCOPED_TRACE(cause);
    const fs::path bench = tmp / (cause + ".yaml"), out = tmp / ("inv-" + cause);
    test::write_file(bench, "temperature: {t0_c: 20, ramp_c_per_s: 0, amplitude_c: 2, period_s: 1200}\neffects:\n  - " +
                                effect + "\n");
    const auto r = run_stand({"investigate", "--model", kModel, "--emulate", "--bench", bench.string(), "--procedure",
                              (test::source_dir() / "procedures/discrete_grid.yaml").string(), "--speed", "20",
                              "--runs-dir", (tmp / ("runs-" + cause)).string(), "--out", out.string(), "--quiet"},
                             tmp.path(), "investigate", 600);
    ASSERT_EQ(r.code, 0) << r.out << r.err;
    const auto inv = nlohmann::json::parse(test::read_file(out / "INVESTIGATION.json"));
    EXPECT_EQ(inv["cause"], cause) << inv.dump(1);
    EXPECT_EQ(inv["verdict"], "explained");
    const char* key = cause == "drift" ? "pitch_arcsec_per_s" : "pitch_arcsec_per_c";
    const double truth = cause == "drift" ? 0.002 : 1.0;
    EXPECT_NEAR(inv["causes"][0]["params"][key].get<double>(), truth, 0.1 * truth);
    EXPECT_LE(inv["bench_time_s"]["followups_ratio"].get<double>(), 1.0);
    // The first run (two-decimal TEMP readings over 181 s of the sine) may already tell them apart;
    // where it does not, the follow-ups ran on the one bench, its clock going on.
    for (size_t k = 1; k < inv["recordings"].size(); ++k) {
      const auto& rec = inv["recordings"][k];
      EXPECT_EQ(rec["clock"], "bench");
      EXPECT_GT(rec["time_span_s"][0].get<double>(), inv["recordings"][k - 1]["time_span_s"][1].get<double>());
      const auto run = nlohmann::json::parse(test::read_file(fs::path(inv["runs"][k].get<std::string>()) / "run.json"));
      EXPECT_EQ(run["sessions"][0]["emulator"]["shared"], true) << run.dump(1);
    }
  }
}

// The loop over a runner that reports runs which did not complete, in-process: the discrete grid
// recorded on the simulated bench with a 4 arcsec backlash (the recording the emulated run makes
// before its check fails), reported as each kind of stop.
class InvestigateStops : public testing::Test {
 protected:
  void SetUp() override {
    test::write_file(tmp_ / "backlash.yaml", "effects:\n  - {name: backlash, width_arcsec: 4}\n");
    const auto r = run_stand({"simulate", "--procedure", (test::source_dir() / "procedures/discrete_grid.yaml").string(),
                              "--bench", (tmp_ / "backlash.yaml").string(), "--seed", "5", "--out", recording().string()},
                             tmp_.path());
    ASSERT_EQ(r.code, 0) << r.err;
    opts_.model = load_coefficients(kModel);
    opts_.model_path = kModel;
    opts_.bench = default_bench_config();  // the emulated bench's, as `investigate --emulate` designs on
    opts_.settings = emulated_settings(opts_.bench);
    opts_.out_dir = tmp_ / "inv";
  }
  fs::path recording() const { return tmp_ / "grid.csv"; }
  InvestigationRun stopped(StopCause cause, int64_t points, const std::string& reason) const {
    InvestigationRun r;
    r.samples = recording();
    r.cause = cause;
    r.reason = reason;
    r.points_done = points;
    return r;
  }
  // The loop with each run reported by `runs` in turn (the runner is not called past them).
  Investigation loop(std::vector<InvestigationRun> runs, const std::optional<InvestigationRun>& from = std::nullopt) {
    return investigate(test::source_dir() / "procedures/discrete_grid.yaml", opts_, [&, runs](const fs::path&, int k) {
      ++calls_;
      return runs.at(static_cast<size_t>(k));
    }, from);
  }
  TempDir tmp_{"investigate-stops"};
  InvestigationOptions opts_;
  int calls_ = 0;
};

TEST_F(InvestigateStops, AFirstRunWhoseCheckFailedIsDiagnosedAndRecordedWithItsStop) {
  opts_.max_runs = 1;
  const Investigation inv = loop({stopped(StopCause::check_failed, 113, "step 5 (check): pitch max |residual| 3.760 arcsec > 2.1 arcsec")});
  ASSERT_TRUE(inv.diagnosed()) << inv.no_diagnosis;
  EXPECT_THAT(inv.stop_reason, testing::AnyOf("max_runs", "ended"));
  EXPECT_FALSE(inv.stopped_by_a_run());
  const auto j = inv.to_json();
  EXPECT_EQ(j["diagnosed"], true);
  EXPECT_FALSE(j.contains("no_diagnosis"));
  const auto& step = j["steps"][0];
  EXPECT_EQ(step["outcome"], "failed");
  EXPECT_EQ(step["stop_cause"], "check_failed");
  EXPECT_THAT(step["stop"].get<std::string>(), HasSubstr("check failed: step 5 (check)"));
  ASSERT_TRUE(step.contains("diagnosis")) << step.dump(1);
  EXPECT_NE(j["cause"], "none") << j.dump(1);
  EXPECT_NE(j["verdict"], "no_gap");
}

// A follow-up whose check fails does not stop the loop either: its recording joins the joint
// diagnosis and the next follow-up is designed and run.
TEST_F(InvestigateStops, AFollowUpWhoseCheckFailedIsDiagnosedAndTheLoopGoesOn) {
  InvestigationRun first = stopped(StopCause::none, 113, "");
  first.completed = true;
  const Investigation inv =
      loop({first, stopped(StopCause::check_failed, 113, "step 4 (check): yaw max |residual| 3.3 arcsec > 2.1 arcsec"), first});
  ASSERT_GE(calls_, 2) << inv.stop_reason << ": " << inv.stop_sentence;  // the first diagnosis left a follow-up to make
  const auto j = inv.to_json();
  const auto& followup = j["steps"][1];
  EXPECT_EQ(followup["stop_cause"], "check_failed");
  EXPECT_TRUE(followup.contains("diagnosis")) << followup.dump(1);
  EXPECT_FALSE(inv.stopped_by_a_run()) << inv.stop_reason;
  EXPECT_EQ(j["recordings"].size(), static_cast<size_t>(calls_));
}

TEST_F(InvestigateStops, AFirstRunStoppedByADeviceFaultBeforeAnyPointEndsWithoutAVerdict) {
  const Investigation inv = loop({stopped(StopCause::gimbal_fault, 0, "gimbal fault code 1")});
  EXPECT_EQ(calls_, 1);
  EXPECT_FALSE(inv.diagnosed());
  EXPECT_TRUE(inv.stopped_by_a_run());
  EXPECT_EQ(inv.stop_reason, "device_fault");
  EXPECT_THAT(inv.stop_sentence, HasSubstr("device fault"));
  EXPECT_EQ(inv.no_diagnosis,
            "the first run failed before any point was recorded (device fault (gimbal_fault): gimbal fault code 1)");
  const auto j = inv.to_json();
  EXPECT_EQ(j["diagnosed"], false);
  for (const char* key : {"verdict", "verdict_sentence", "cause", "causes"}) EXPECT_FALSE(j.contains(key)) << key;
  EXPECT_EQ(j["steps"][0]["stop_cause"], "gimbal_fault");
  EXPECT_THAT(j.dump(), Not(HasSubstr("no_gap")));
}

TEST_F(InvestigateStops, ADeviceFaultPartWayIsNotDiagnosedAndAnAbortIsButEndsTheLoop) {
  Investigation inv = loop({stopped(StopCause::sensor_timeout, 40, "no frame for 2 s")});
  EXPECT_FALSE(inv.diagnosed());
  EXPECT_THAT(inv.no_diagnosis, HasSubstr("not diagnosed (device fault (sensor_timeout)"));
  EXPECT_THAT(inv.stop_sentence, HasSubstr("after 40 points"));
  calls_ = 0;
  inv = loop({stopped(StopCause::aborted, 113, "aborted by the operator")});
  EXPECT_EQ(calls_, 1);
  EXPECT_TRUE(inv.diagnosed());
  EXPECT_EQ(inv.stop_reason, "run_stopped");
  EXPECT_EQ(inv.to_json()["steps"][0]["outcome"], "interrupted");
}

TEST_F(InvestigateStops, ARunMadeEarlierIsTheFirstAndNoRunIsMadeForIt) {
  opts_.max_runs = 1;
  InvestigationRun earlier = stopped(StopCause::none, 113, "");
  earlier.completed = true;
  earlier.acceptance = "fail";
  earlier.run_dir = tmp_ / "runs/earlier";
  const Investigation inv = loop({}, earlier);
  EXPECT_EQ(calls_, 0);
  ASSERT_TRUE(inv.diagnosed());
  const auto j = inv.to_json();
  EXPECT_EQ(j["runs"][0], earlier.run_dir.string());
  EXPECT_EQ(j["steps"][0]["why"], "a run made earlier (--from)");
  EXPECT_EQ(j["steps"][0]["outcome"], "completed");
  EXPECT_EQ(j["steps"][0]["acceptance"], "fail");
}

// The case over the wire: the grid's own check fails on a 4 arcsec backlash (pitch max
// |residual| about 3.8 arcsec > 2.1). The failed run is diagnosed and the loop goes on; the same
// run diagnosed again by `diagnose --run`, and investigated again `--from` it.
TEST(Investigate, OnTheEmulatedBenchAGridWhoseCheckFailsIsDiagnosedAndTheLoopGoesOn) {
  TempDir tmp("investigate-check-failed");
  const fs::path runs = tmp / "runs", out = tmp / "inv";
  const auto r = run_stand({"investigate", "--model", kModel, "--emulate", "--effect", "backlash:width_arcsec=4",
                            "--procedure", (test::source_dir() / "procedures/discrete_grid.yaml").string(), "--speed",
                            "20", "--runs-dir", runs.string(), "--out", out.string(), "--quiet", "--max-runs", "2"},
                           tmp.path(), "investigate", 600);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_THAT(r.out, Not(HasSubstr("run_failed")));
  EXPECT_THAT(r.out, HasSubstr("run 1: check failed: "));
  EXPECT_THAT(r.out, HasSubstr("verdict: "));
  const auto inv = nlohmann::json::parse(test::read_file(out / "INVESTIGATION.json"));
  ASSERT_GE(inv["steps"].size(), 1u);
  const auto& first = inv["steps"][0];
  EXPECT_EQ(first["outcome"], "failed") << first.dump(1);
  EXPECT_EQ(first["stop_cause"], "check_failed");
  EXPECT_THAT(first["stop"].get<std::string>(), HasSubstr("pitch max |residual|"));
  ASSERT_TRUE(first.contains("diagnosis")) << first.dump(1);
  EXPECT_EQ(inv["diagnosed"], true);
  ASSERT_FALSE(inv["causes"].empty()) << inv.dump(1);
  EXPECT_NE(inv["verdict"], "no_gap");
  // What it names, for the record (the target: backlash alone, its width within 10 % of 4).
  std::string named;
  for (const auto& c : inv["causes"]) named += c["name"].get<std::string>() + " " + c["params"].dump() + "; ";
  RecordProperty("causes", named);
  std::printf("backlash grid: first run %s; investigation names %s(stop: %s)\n",
              first["diagnosis"]["cause"].dump().c_str(), named.c_str(), inv["stop_reason"].get<std::string>().c_str());
  const fs::path run1 = inv["runs"][0].get<std::string>();

  // diagnose --run: the failed run's recording, its outcome said and recorded.
  const auto d = run_stand({"diagnose", "--run", run1.string(), "--model", kModel, "--out", (tmp / "gap.json").string(),
                            "--partial"},
                           tmp.path(), "diagnose");
  ASSERT_EQ(d.code, 0) << d.out << d.err;
  EXPECT_THAT(d.out, HasSubstr(": failed (check_failed): step"));
  EXPECT_THAT(d.out, HasSubstr("verdict: "));
  const auto gap = nlohmann::json::parse(test::read_file(tmp / "gap.json"));
  EXPECT_EQ(gap["run"]["outcome"], "failed");
  EXPECT_EQ(gap["run"]["stop_cause"], "check_failed");
  EXPECT_EQ(gap["cause"], first["diagnosis"]["cause"]);
  // The grid's procedure names no model: --model is needed, and the message says so.
  const auto no_model = run_stand({"diagnose", "--run", run1.string(), "--out", (tmp / "gap2.json").string()}, tmp.path(),
                                  "diagnose-no-model");
  EXPECT_EQ(no_model.code, 2);
  EXPECT_THAT(no_model.err, HasSubstr("give --model"));

  // investigate --from: the same run first, no run made for it.
  const auto again = run_stand({"investigate", "--model", kModel, "--emulate", "--from", run1.string(), "--max-runs", "1",
                                "--runs-dir", runs.string(), "--out", (tmp / "inv-from").string(), "--quiet"},
                               tmp.path(), "investigate-from", 300);
  ASSERT_EQ(again.code, 0) << again.out << again.err;
  const auto from = nlohmann::json::parse(test::read_file(tmp / "inv-from/INVESTIGATION.json"));
  ASSERT_EQ(from["runs"].size(), 1u);
  EXPECT_EQ(from["runs"][0], run1.string());
  EXPECT_EQ(from["steps"][0]["why"], "a run made earlier (--from)");
  EXPECT_EQ(from["steps"][0]["stop_cause"], "check_failed");
  EXPECT_EQ(from["steps"][0]["diagnosis"]["cause"], first["diagnosis"]["cause"]);
}

// A device fault before the first point (the sensor silent from the start: its link fails before
// the run begins): the loop ends saying so, without a verdict.
TEST(Investigate, OnTheEmulatedBenchASilentSensorAtTheStartEndsWithoutAVerdict) {
  TempDir tmp("investigate-device-fault");
  const fs::path out = tmp / "inv";
  const auto r = run_stand({"investigate", "--model", kModel, "--emulate", "--fault", "sensor_silence:duration_s=100000",
                            "--procedure", (test::source_dir() / "procedures/discrete_grid.yaml").string(), "--speed",
                            "20", "--runs-dir", (tmp / "runs").string(), "--out", out.string(), "--quiet"},
                           tmp.path(), "investigate", 300);
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("investigation: device_fault"));
  EXPECT_THAT(r.out, HasSubstr("no diagnosis: the first run failed before any point was recorded (device fault"));
  EXPECT_THAT(r.out, Not(HasSubstr("verdict")));
  EXPECT_THAT(r.out, Not(HasSubstr("no_gap")));
  const auto inv = nlohmann::json::parse(test::read_file(out / "INVESTIGATION.json"));
  EXPECT_EQ(inv["diagnosed"], false);
  EXPECT_FALSE(inv.contains("verdict"));
  EXPECT_EQ(inv["stop_reason"], "device_fault");
  EXPECT_THAT(inv["steps"][0]["stop"].get<std::string>(), HasSubstr("device fault"));
  const std::string page = test::read_file(out / "INVESTIGATION.html");
  EXPECT_THAT(page, HasSubstr("No diagnosis: the first run failed"));
  EXPECT_THAT(page, Not(HasSubstr("no_gap")));
}

// An acceptance whose residual criteria fail (a 4 arcsec backlash) completes its run: diagnose --run
// and investigate --from take its recording, saying the acceptance failed.
TEST(Investigate, AnAcceptanceThatFailedIsDiagnosedAndInvestigatedFrom) {
  TempDir tmp("investigate-from-accept");
  const fs::path runs = tmp / "runs";
  const auto acc = run_stand({"accept", "--emulate", "--quiet", "--speed", "40", "--runs-dir", runs.string(), "--effect",
                              "backlash:width_arcsec=4"},
                             tmp.path(), "accept", 300);
  ASSERT_EQ(acc.code, 3) << acc.out << acc.err;  // the acceptance failed
  const auto dirs = test::run_dirs(runs);
  ASSERT_EQ(dirs.size(), 1u);
  const fs::path run = dirs.front();
  const auto d = run_stand({"diagnose", "--run", run.string(), "--model", kModel, "--out", (tmp / "gap.json").string(),
                            "--partial"},
                           tmp.path(), "diagnose");
  ASSERT_EQ(d.code, 0) << d.out << d.err;
  EXPECT_THAT(d.out, HasSubstr(": completed, acceptance fail (residual_"));
  const auto gap = nlohmann::json::parse(test::read_file(tmp / "gap.json"));
  EXPECT_EQ(gap["run"]["acceptance"], "fail");
  EXPECT_EQ(gap["run"]["outcome"], "completed");
  const auto inv = run_stand({"investigate", "--model", kModel, "--emulate", "--from", run.string(), "--max-runs", "1",
                              "--runs-dir", runs.string(), "--out", (tmp / "inv").string(), "--quiet"},
                             tmp.path(), "investigate-from", 300);
  ASSERT_EQ(inv.code, 0) << inv.out << inv.err;
  EXPECT_THAT(inv.out, HasSubstr("run 1: completed, acceptance failed"));
  const auto j = nlohmann::json::parse(test::read_file(tmp / "inv/INVESTIGATION.json"));
  EXPECT_EQ(j["steps"][0]["acceptance"], "fail");
  EXPECT_EQ(j["steps"][0]["why"], "a run made earlier (--from)");
  EXPECT_EQ(j["cause"], gap["cause"]);
}

// diagnose --run without --model: the model the run's procedure names in its diagnose step (a step
// the run never reached: its check failed first).
TEST(Investigate, DiagnoseRunTakesTheModelTheRunsProcedureNames) {
  TempDir tmp("diagnose-run-model");
  const std::string grid = test::read_file(test::source_dir() / "procedures/discrete_grid.yaml");
  test::write_file(tmp / "grid.yaml", grid + "  - diagnose: {model: \"" + kModel + "\", partial: true}\n");
  const fs::path runs = tmp / "runs";
  const auto r = run_stand({"run", (tmp / "grid.yaml").string(), "--emulate", "--speed", "20", "--effect",
                            "backlash:width_arcsec=4", "--runs-dir", runs.string(), "--quiet", "--no-progress"},
                           tmp.path(), "run", 300);
  ASSERT_EQ(r.code, 1) << r.err;  // its check failed
  const auto dirs = test::run_dirs(runs);
  ASSERT_EQ(dirs.size(), 1u);
  const auto d = run_stand({"diagnose", "--run", dirs.front().string(), "--out", (tmp / "gap.json").string(), "--partial"},
                           tmp.path(), "diagnose");
  ASSERT_EQ(d.code, 0) << d.out << d.err;
  const auto gap = nlohmann::json::parse(test::read_file(tmp / "gap.json"));
  EXPECT_EQ(gap["model"], kModel);
  EXPECT_EQ(gap["run"]["stop_cause"], "check_failed");
  EXPECT_FALSE(fs::exists(dirs.front() / "GAP.json"));  // the run's own diagnose step never ran
}

// investigate --from and diagnose --run of a run folder that is not one: exit 2 naming the option.
TEST(Investigate, FromAFolderThatIsNoRunExitsTwoNamingTheOption) {
  TempDir tmp("investigate-from-bad");
  fs::create_directories(tmp / "empty");
  const auto r = run_stand({"investigate", "--model", kModel, "--emulate", "--from", (tmp / "empty").string(), "--out",
                            (tmp / "inv").string(), "--quiet"},
                           tmp.path(), "investigate-from-bad");
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("run.json"));
  const auto both = run_stand({"investigate", "--model", kModel, "--emulate", "--from", (tmp / "empty").string(),
                               "--procedure", (test::source_dir() / "procedures/discrete_grid.yaml").string()},
                              tmp.path(), "investigate-from-both");
  EXPECT_EQ(both.code, 2) << both.err;
  const auto d = run_stand({"diagnose", "--run", (tmp / "nothing").string(), "--model", kModel, "--out",
                            (tmp / "g.json").string()},
                           tmp.path(), "diagnose-bad");
  EXPECT_EQ(d.code, 2) << d.err;
  EXPECT_THAT(d.err, HasSubstr("--run"));
}

TEST(Investigate, ConfusableCasesAreToldApartWithinTheBudget) {
  TempDir tmp("confusable");
  const ConfusableReport rep = run_confusable_cases(1, 2, tmp.path());
  ASSERT_EQ(rep.cases.size(), confusable_kinds().size());
  for (const auto& c : rep.cases) {
    SCOPED_TRACE(c.kind + ": " + c.truth);
    EXPECT_LE(c.followups, 2);
    EXPECT_LE(c.followup_ratio, 1.0);
    EXPECT_TRUE(c.success()) << c.main_error;
    if (c.kind == "unambiguous") {
      EXPECT_EQ(c.followups, 0);
    }
  }
}

}  // namespace
}  // namespace fpss
