// A diagnose step in a procedure: the run writes GAP.json and GAP.html into its folder and names
// them in run.json; the shipped sim_to_real.yaml is diagnosable whole; a model file that cannot be
// read stops the run before anything moves.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "base/text_file.h"
#include "calib/samples.h"
#include "tests/procedures/run_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {
namespace fs = std::filesystem;
using test::run_stand;
using test::TempDir;

const std::string kModel = (test::source_dir() / "calib/data/published/a-6-fpss1.json").string();

std::string procedure(const std::string& model) {
  return "steps:\n  - home\n"
         "  - null_offset_grid: {extent_deg: 0.3, step_deg: 0.1, frames: 10, settle_s: 0.2}\n"
         "  - diagnose: {model: " + model + ", settle_s: 0.2, partial: true}\n";
}

TEST(DiagnoseStep, WritesTheGapFilesIntoTheRunFolder) {
  TempDir tmp("diagnose-step");
  test::write_file(tmp / "p.yaml", procedure(kModel));
  const auto r = run_stand({"run", (tmp / "p.yaml").string(), "--emulate", "--speed", "50", "--runs-dir",
                            (tmp / "runs").string(), "--no-progress"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto dirs = test::run_dirs(tmp / "runs");
  ASSERT_EQ(dirs.size(), 1u);
  const auto gap = nlohmann::json::parse(test::read_file(dirs.front() / "GAP.json"));
  // The emulator without effects, against its own truth: nothing beyond the noise.
  EXPECT_EQ(gap["verdict"], "no_gap") << gap.dump(1);
  EXPECT_EQ(gap["model"], kModel);
  EXPECT_NE(test::read_file(dirs.front() / "GAP.html").find("<html"), std::string::npos);
  const auto run = nlohmann::json::parse(test::read_file(dirs.front() / "run.json"));
  EXPECT_EQ(run["files"]["gap"], "GAP.json");
  EXPECT_EQ(run["outcome"], "completed");
}

// A dwells-only grid on a bench that drifts while its temperature ramps (0.05 C/s: the temperature
// follows time): the drift is named with the temperature beside it (a look-alike this recording
// cannot score), and the run's own diagnose step gives that set its follow-up, as `diagnose` does.
TEST(DiagnoseStep, ALookAlikeSetGetsItsFollowUpInTheRunsOwnDiagnosis) {
  TempDir tmp("diagnose-step-followup");
  test::write_file(tmp / "p.yaml", procedure(kModel));
  test::write_file(tmp / "bench.yaml", "temperature: {ramp_c_per_s: 0.05}\n");
  const auto r = run_stand({"run", (tmp / "p.yaml").string(), "--emulate", "--bench", (tmp / "bench.yaml").string(),
                            "--speed", "50", "--runs-dir", (tmp / "runs").string(), "--no-progress", "--effect",
                            "drift:pitch_arcsec_per_s=0.02,yaw_arcsec_per_s=0"},
                           tmp.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto dirs = test::run_dirs(tmp / "runs");
  ASSERT_EQ(dirs.size(), 1u);
  const auto gap = nlohmann::json::parse(test::read_file(dirs.front() / "GAP.json"));
  ASSERT_FALSE(gap["ambiguous"].empty()) << gap.dump(1);
  EXPECT_EQ(gap["ambiguous"][0]["members"], nlohmann::json::array({"drift", "temperature"}));
  for (const auto& set : gap["ambiguous"]) {
    ASSERT_TRUE(set.contains("best_followup")) << set.dump(1);
    EXPECT_TRUE(set["best_followup"].is_object()) << set.dump(1);
    EXPECT_TRUE(set["best_followup"].contains("moves")) << set.dump(1);
  }
}

// The shipped sim_to_real.yaml on the emulator with a backlash and a time shift: its slews reverse
// inside their segments, and its own diagnose step (no `partial`) finds both with nothing
// unobservable that every diagnosis needs. Bench time ~4 min, ~50 s wall at speed-up 5: a slew frame
// is kept only between gimbal readings at most 0.05 bench seconds apart (10 ms of wall time here),
// which at higher speed-ups a host loaded by the other tests misses (at 10x, once in a few full
// runs: frames lost at the segments' ends, or one kept with a poor reference: an outlier the
// diagnosis rightly reports as a remainder of its own).
TEST(DiagnoseStep, TheShippedSimToRealRunIsDiagnosableWhole) {
  TempDir tmp("diagnose-sim-to-real");
  const auto r = run_stand({"run", (test::source_dir() / "procedures/sim_to_real.yaml").string(), "--emulate",
                            "--speed", "5", "--runs-dir", (tmp / "runs").string(), "--no-progress", "--effect",
                            "backlash:width_arcsec=2", "--effect", "time_skew:skew_s=0.03"},
                           tmp.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto dirs = test::run_dirs(tmp / "runs");
  ASSERT_EQ(dirs.size(), 1u);
  // Every slew segment turns inside itself: along the slewed axis its reference goes from one end
  // to the other and back (first and last rows both far from the turning extreme).
  const SampleTable t = read_samples_csv(dirs.front() / "samples.csv");
  int reversing = 0, slews = 0;
  for (size_t i = 0; i < t.size();) {
    size_t j = i;
    double lo = 1e300, hi = -1e300;
    auto x = [&](size_t k) { return t.ref_pitch_arcsec[k] + t.ref_yaw_arcsec[k]; };
    for (; j < t.size() && t.step[j] == t.step[i]; ++j) {
      lo = std::min(lo, x(j));
      hi = std::max(hi, x(j));
    }
    if (t.phase[i] == Phase::slew) {
      ++slews;
      const double first = x(i), last = x(j - 1);
      const double far = std::abs(hi - first) > std::abs(lo - first) ? hi : lo;
      if (std::abs(far - first) > 2000 && std::abs(far - last) > 1000) ++reversing;
    }
    i = j;
  }
  EXPECT_EQ(slews, 8);
  EXPECT_EQ(reversing, 8);
  const auto gap = nlohmann::json::parse(test::read_file(dirs.front() / "GAP.json"));
  for (const auto& n : gap["not_observable"]) EXPECT_FALSE(n["incomplete_recording"].get<bool>()) << n.dump();
  std::set<std::string> causes;
  for (const auto& c : gap["causes"]) causes.insert(c["name"].get<std::string>());
  EXPECT_EQ(causes, (std::set<std::string>{"backlash", "time_skew"})) << gap.dump(1);
  for (const auto& c : gap["causes"]) {
    if (c["name"] == "backlash") {
      EXPECT_NEAR(c["params"]["width_arcsec"].get<double>(), 2.0, 0.1);
    }
    if (c["name"] == "time_skew") {
      EXPECT_NEAR(c["params"]["skew_s"].get<double>(), 0.03, 0.0015);
    }
  }
  EXPECT_EQ(gap["verdict"], "explained") << gap.dump(1);
}

TEST(DiagnoseStep, AnUnreadableModelIsExitTwoBeforeAnythingMoves) {
  TempDir tmp("diagnose-step-bad");
  test::write_file(tmp / "p.yaml", procedure("missing.json"));
  const auto r = run_stand({"run", (tmp / "p.yaml").string(), "--emulate", "--runs-dir", (tmp / "runs").string()},
                           tmp.path());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("field model"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("p.yaml:4"), std::string::npos) << r.err;
  EXPECT_TRUE(test::run_dirs(tmp / "runs").empty());
}

}  // namespace
}  // namespace fpss
