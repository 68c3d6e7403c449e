// A diagnose step in a procedure: the run writes GAP.json and GAP.html into its folder and names
// them in run.json; a model file that cannot be read stops the run before anything moves.
#include <gtest/gtest.h>

#include <filesystem>

#include <nlohmann/json.hpp>

#include "calib/text_file.h"
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
