// fpss-stand design: the cheapest null-to-offset calibration reaching a target 1-sigma, as a
// procedure file the stand runs; targets it cannot reach and bad input are said, not written.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "procedures/plan.h"
#include "procedures/procedure.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {
namespace fs = std::filesystem;
using test::run_stand;
using test::TempDir;

// The target is the paper grid's own largest sigma on this bench (the design prints it, judged like
// its own under every published transfer function): the design reaches it in under half the time.
TEST(Design, ReachesThePapersGridSigmaInHalfItsBenchTimeAndWritesTheProcedure) {
  TempDir tmp("design");
  const auto first = run_stand({"design", "--target-sigma-arcsec", "0.05", "--emulate", "--json"}, tmp.path());
  ASSERT_EQ(first.code, 0) << first.err;
  const auto grid = nlohmann::json::parse(first.out)["paper_grid"];
  const double target = std::max(grid["max_sigma_arcsec_pitch"].get<double>(), grid["max_sigma_arcsec_yaw"].get<double>());
  EXPECT_NEAR(target, 0.021, 0.001);
  const fs::path out = tmp / "designed.yaml";
  const auto r = run_stand({"design", "--target-sigma-arcsec", std::to_string(target), "--emulate", "--out",
                            out.string(), "--json"}, tmp.path());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["reached"].get<bool>());
  EXPECT_LE(j["max_sigma_arcsec_pitch"].get<double>(), target);
  EXPECT_LE(j["max_sigma_arcsec_yaw"].get<double>(), target);
  EXPECT_EQ(j["inputs"]["robust_over"].size(), 11u);  // the 14 published sets but the three suspect
  EXPECT_LE(j["bench_time_s"].get<double>(), 0.5 * j["paper_grid"]["bench_time_s"].get<double>());
  // The file is a procedure whose dry run predicts the design's bench time.
  const Procedure p = load_procedure(out);
  Diagnostics d(out.string());
  const Plan plan = expand(p, EngineSettings{}, d);
  ASSERT_TRUE(d.empty()) << d.text();
  EXPECT_EQ(plan.points, 2 * j["offsets"].get<size_t>() + 1);
  EXPECT_NEAR(plan.estimated_s, j["bench_time_s"].get<double>(), 0.05 * j["bench_time_s"].get<double>());
}

TEST(Design, AnUnreachableTargetIsExitOneAndNoFile) {
  TempDir tmp("design-unreachable");
  const fs::path out = tmp / "never.yaml";
  const auto r = run_stand({"design", "--target-sigma-arcsec", "0.000001", "--emulate", "--out", out.string()},
                           tmp.path());
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.out.find("TARGET NOT REACHED"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(out));
}

TEST(Design, BadInputIsExitTwoNamingIt) {
  TempDir tmp("design-bad");
  auto r = run_stand({"design", "--target-sigma-arcsec", "-1", "--emulate"}, tmp.path());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--target-sigma-arcsec"), std::string::npos) << r.err;
  r = run_stand({"design", "--target-sigma-arcsec", "0.02", "--stand", (tmp / "missing.yaml").string()}, tmp.path());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("missing.yaml"), std::string::npos) << r.err;
  r = run_stand({"design", "--target-sigma-arcsec", "0.02", "--bench", "x.yaml"}, tmp.path());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--bench needs --emulate"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace fpss
