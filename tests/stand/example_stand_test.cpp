// The shipped stand files against the emulated bench: procedures/emulator_stand.yaml against a
// running `fpss-stand emulate` (its own process, as an operator starts it) calibrates within the
// paper's limits; the paper's mounting (procedures/example_stand.yaml) against the emulator's
// sensor gives absurd residuals, and the run says the axis mapping is the likely cause; on an
// emulator mounted the paper's way (procedures/paper_mount_bench.yaml) it fits.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "tests/procedures/run_util.h"
#include "tests/stand/emulator_stand.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using testing::HasSubstr;
using testing::Not;

std::string procedures(const char* name) { return test::shipped_procedure(name); }

TEST(ExampleStand, TheEmulatorStandFileCalibratesWithinTheLimitsAgainstARunningEmulate) {
  test::TempDir tmp("example-stand");
  test::EmulatorStand es(tmp);
  ASSERT_FALSE(es.stand_file.empty());
  const fs::path stand_file = es.stand_file;
  const fs::path runs = tmp / "runs";
  const auto r = test::run_stand({"run", procedures("discrete_grid.yaml"), "--stand", stand_file.string(), "--runs-dir",
                                  runs.string()}, tmp.path(), "run", 300);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("check: residuals within the limits"));
  const auto cal = nlohmann::json::parse(test::read_file(test::run_dirs(runs).at(0) / "calibration.json"));
  for (const char* axis : {"pitch", "yaw"}) {
    EXPECT_LE(cal["residuals"][axis]["mean_abs_arcsec"].get<double>(), 0.8) << axis;
    EXPECT_LE(cal["residuals"][axis]["max_abs_arcsec"].get<double>(), 2.1) << axis;
  }
  es.emu.signal(SIGTERM);
  EXPECT_EQ(es.emu.wait(30), 0);
}

// The paper's mounting on the emulator's sensor: hundreds of arcsec, and the run says why.
TEST(ExampleStand, ThePapersMountingOnTheEmulatorsSensorNamesTheAxisMapping) {
  test::TempDir tmp("paper-mount");
  const fs::path runs = tmp / "runs";
  const auto r = test::run_stand({"run", procedures("discrete_grid.yaml"), "--stand", procedures("example_stand.yaml"),
                                  "--emulate", "--unit-serial", "FPSS1-SN042", "--speed", "50", "--runs-dir",
                                  runs.string()}, tmp.path(), "run", 300);
  ASSERT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("Residuals over 100x the limit: the likely cause is the stand file's axis mapping"));
  EXPECT_THAT(r.out, Not(HasSubstr("resume with:")));  // every point was measured
  const std::string page = test::read_file(test::run_dirs(runs).at(0) / "report.html");
  EXPECT_THAT(page, HasSubstr(">FAIL<"));
  EXPECT_THAT(page, HasSubstr("axis mapping"));
}

// The same stand file on an emulator whose sensor is mounted the paper's way (the shipped bench
// file): within the limits, so the mapping, not the file, was what did not fit.
TEST(ExampleStand, ThePapersMountingFitsAnEmulatorMountedThePapersWay) {
  test::TempDir tmp("paper-bench");
  const fs::path runs = tmp / "runs";
  const auto r = test::run_stand({"run", procedures("discrete_grid.yaml"), "--stand", procedures("example_stand.yaml"),
                                  "--emulate", "--bench", procedures("paper_mount_bench.yaml"), "--unit-serial",
                                  "FPSS1-SN042", "--speed", "50", "--runs-dir", runs.string()}, tmp.path(), "run", 300);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("check: residuals within the limits"));
}

}  // namespace
}  // namespace fpss
