// fpss-stand calibrate end to end: the contract's command line, its files and exit codes.
#include <gtest/gtest.h>

#include <filesystem>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "calib/samples.h"
#include "fixtures/recording.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;

using Result = test::CommandResult;

class Command : public ::testing::Test {
 protected:
  Result run(const std::string& args) const { return test::run_stand_shell("calibrate " + args, dir_.path()); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string write(const std::string& name, const std::string& text) const { return dir_.write(name, text).string(); }
  std::string recording(const std::string& name, GridPlan plan = {}) const {
    BenchConfig cfg = default_bench_config();
    cfg.truth = load_published("a-5-fpss1");
    write_samples_csv(dir_ / name, simulate_null_offset(cfg, plan));
    return path(name);
  }

  test::TempDir dir_{"cmd-calibrate"};
};

const std::string kTruth = std::string(FPSS_SOURCE_DIR) + "/calib/data/published/a-5-fpss1.json";

TEST_F(Command, WritesTheCoefficientFileWithResidualsAndPrintsTableOne) {
  const std::string data = recording("rec.csv");
  const Result r = run("--data " + data + " --out " + path("cal.json") + " --truth " + kTruth);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("pitch (alpha)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("mean residual (arcsec)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Fit minus truth"), std::string::npos) << r.out;
  const CoefficientSet s = load_coefficients(path("cal.json"));
  EXPECT_EQ(s.unit, "FPSS1");  // from --truth when no --unit or --init
  const auto& res = s.extra.at("residuals");
  for (const char* axis : {"pitch", "yaw"}) {
    for (const char* k : {"mean_abs_arcsec", "sd_arcsec", "max_abs_arcsec", "points", "range_deg"}) {
      EXPECT_TRUE(res.at(axis).contains(k)) << axis << " " << k;
    }
    EXPECT_LT(s.extra.at("truth_comparison").at(axis).at("max_abs_arcsec").get<double>(), 0.1);
  }
  EXPECT_EQ(s.extra.at("source"), data);
  EXPECT_EQ(s.extra.at("method"), "differences");
}

TEST_F(Command, MonteCarloChecksTheBudgetIntoTheCoefficientFile) {
  const std::string data = recording("rec.csv");
  const std::string ref = std::string(FPSS_SOURCE_DIR) + "/procedures/reference_example.json";
  const Result r = run("--data " + data + " --out " + path("cal.json") + " --reference " + ref + " --monte-carlo 20000");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("Monte Carlo check of the budget (JCGM 101, 20000 trials, seed 1)"), std::string::npos) << r.out;
  const CoefficientSet s = load_coefficients(path("cal.json"));
  const auto& mc = s.extra.at("monte_carlo");
  EXPECT_EQ(mc.at("trials"), 20000);
  for (const char* axis : {"pitch", "yaw"}) {
    const auto& a = mc.at(axis);
    // The check is of the budget calibration.json states: the same U, at the same angle.
    EXPECT_EQ(a.at("gum_expanded_uncertainty_arcsec"), s.extra.at("uncertainties").at(axis).at("expanded_uncertainty_max_arcsec"));
    EXPECT_EQ(a.at("angle_arcsec"), s.extra.at("uncertainties").at(axis).at("budget_angle_arcsec"));
    EXPECT_NEAR(a.at("u_arcsec").get<double>(), a.at("gum_u_arcsec").get<double>(), 0.03 * a.at("gum_u_arcsec").get<double>());
  }
  const Result bad = run("--data " + data + " --out " + path("cal2.json") + " --monte-carlo 10");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("--monte-carlo"), std::string::npos) << bad.err;
}

TEST_F(Command, AbsoluteMethodStartSetAndUnit) {
  const std::string data = recording("rec.csv");
  const Result r = run("--data " + data + " --out " + path("cal.json") + " --method absolute --init " + kTruth +
                       " --unit SN-42");
  ASSERT_EQ(r.code, 0) << r.err;
  const CoefficientSet s = load_coefficients(path("cal.json"));
  EXPECT_EQ(s.unit, "SN-42");
  EXPECT_EQ(s.extra.at("method"), "absolute");
}

TEST_F(Command, BadInputExitsTwoWithAClearMessageAndWritesNothing) {
  const std::string data = recording("rec.csv");
  const std::string out = path("cal.json");
  struct Case {
    std::string args, message;
  };
  const std::string h = "time_s,phase,step,ref_pitch_arcsec,ref_yaw_arcsec,counts_alpha,counts_beta\n";
  GridPlan pitch_only;
  pitch_only.yaw = false;
  const std::vector<Case> cases = {
      {"--data " + write("bad.csv", h + "0,null,1,0,0,12x,0\n") + " --out " + out,
       "bad.csv:2: column \"counts_alpha\": expected a finite number, got \"12x\""},
      {"--data " + write("nocol.csv", "time_s,phase,step\n0,null,1\n") + " --out " + out,
       "missing required column \"ref_pitch_arcsec\""},
      {"--data " + write("back.csv", h + "1,null,1,0,0,0,0\n0,null,1,0,0,0,0\n") + " --out " + out,
       "time goes backwards"},
      {"--data " + recording("pitch.csv", pitch_only) + " --out " + out, "no offsets along yaw"},
      {"--data " + write("few.csv", h + "0,null,1,0,0,0,0\n1,offset,2,100,100,900,900\n2,null,3,0,0,0,0\n") +
           " --out " + out,
       "too few points"},
      {"--data " + path("absent.csv") + " --out " + out, "cannot open samples file"},
      {"--data " + data + " --out " + out + " --init " + write("init.json", "{\"alpha\": [1,2,3"),
       "not valid JSON"},
      {"--data " + data + " --out " + out + " --truth " +
           write("t.json", R"({"alpha": [1,2,3,4,5,6,7], "beta": [1,2,3,4,5,6,7,8]})"),
       "must be an array of 8 numbers"},
      {"--data " + data + " --out " + out + " --method relative", "relative"},
      {"--out " + out, "--data is required"},
  };
  for (const auto& c : cases) {
    const Result r = run(c.args);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_FALSE(fs::exists(out)) << c.args;
  }
}

TEST_F(Command, Help) {
  const Result r = run("--help");
  EXPECT_EQ(r.code, 0);
  for (const char* opt : {"--data", "--out", "--init", "--method", "--truth", "--unit"}) {
    EXPECT_NE(r.out.find(opt), std::string::npos) << opt;
  }
}

}  // namespace
}  // namespace fpss
