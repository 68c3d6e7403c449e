// The measurement-system analysis of an emulated fleet on a real PostgreSQL server: three stands,
// one whose gimbal's encoders carry a 200 ppm scale error, five units, two repeats; the erring stand
// shows as reproducibility, and an independent ANOVA (tests/gen/msa_anova.py, numpy) agrees.
#include <gtest/gtest.h>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "tests/support/pg_server.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;

constexpr int kUnits = 5, kRepeats = 2;
const char* const kStands[] = {"stand-A", "stand-B", "stand-C"};  // stand-C's encoders read 200 ppm long

// One stand's runs (its units in turn, twice), started as one shell loop so the stands run at once.
std::vector<std::string> stand_runs(const fs::path& dir, const std::string& stand, const std::string& url, bool erring) {
  test::write_file(dir / "stand.yaml", fmt::format("stand: {}\ncatalogue: {}\ngimbal:\n  endpoint: modbus-tcp:127.0.0.1:1\n"
                                                   "sensor:\n  endpoint: serial:/dev/null:115200\n",
                                                   stand, url));
  const std::string ppm = R"({"value": 200, "u": 0})", zero = R"({"value": 0, "u": 0})";
  const std::string axis = fmt::format(R"({{"scale_factor_ppm": {}, "nonorthogonality_arcsec": {}, "zero_arcsec": {}, "cyclic": []}})",
                                       erring ? ppm : zero, zero, zero);
  test::write_file(dir / "errors.json", fmt::format(R"({{"certificate": "TRUE", "date": "2026-01-01", "lab": "test", "pitch": {0}, "yaw": {0}}})", axis));
  test::write_file(dir / "bench.yaml", "gimbal_errors: errors.json\n");
  std::string script = "set -e\n";
  for (int k = 0; k < kRepeats; ++k) {
    for (int u = 0; u < kUnits; ++u) {
      // Units are the published sets A-2..A-6 of FPSS1: five real transfer functions.
      script += fmt::format(
          "'{}' run '{}' --emulate --speed 50 --quiet --no-progress --stand '{}' --bench '{}' --runs-dir '{}' "
          "--unit-serial SN-{} --truth '{}' --seed {}\n",
          test::stand_binary().string(), (test::source_dir() / "procedures" / "discrete_grid.yaml").string(),
          (dir / "stand.yaml").string(), (dir / "bench.yaml").string(), (dir / "runs").string(), u,
          (test::source_dir() / "calib" / "data" / "published" / fmt::format("a-{}-fpss1.json", u + 2)).string(),
          100 * k + 10 * u + (stand.back() - 'A') + 1);
    }
  }
  return {"/bin/sh", "-c", script};
}

TEST(MsaFleet, TheErringStandShowsAsReproducibilityAndAnIndependentAnovaAgrees) {
  test::PgServer pg;
  const std::string url = pg.create_database("msa_fleet");
  test::TempDir tmp("msa-fleet");
  std::vector<std::unique_ptr<test::Child>> stands;
  for (const char* s : kStands) {
    const fs::path dir = tmp / s;
    fs::create_directories(dir);
    stands.push_back(std::make_unique<test::Child>(stand_runs(dir, s, url, std::string(s) == "stand-C"),
                                                   dir / "runs.out", dir / "runs.err"));
  }
  for (size_t i = 0; i < stands.size(); ++i) {
    ASSERT_EQ(stands[i]->wait(400), 0) << kStands[i] << ": " << stands[i]->err();
  }
  const fs::path out = tmp / "msa.json";
  const auto r = test::run_stand({"msa", "--catalogue", url, "--out", out.string(), "--report", (tmp / "msa.html").string()},
                                 tmp.path(), "msa");
  ASSERT_EQ(r.code, 0) << r.err;
  std::printf("%s", r.out.c_str());  // the study's reading per quantity, for the log
  const auto m = nlohmann::json::parse(test::read_file(out));
  EXPECT_EQ(m["units"].size(), 5u);
  EXPECT_EQ(m["stands"], nlohmann::json({"stand-A", "stand-B", "stand-C"}));
  EXPECT_EQ(m["repeats"], kRepeats);
  // Stand C's calibrated angle minus stand A's, per unit and repeat: its mean and standard error
  // (the emulated runs run against the wall clock, so the figures vary from run to run).
  const auto c_minus_a = [&](const char* q) {
    const auto& v = m["quantities"][q]["values"];
    std::vector<double> d;
    for (int u = 0; u < kUnits; ++u) {
      for (int k = 0; k < kRepeats; ++k) d.push_back(v[u][2][k].get<double>() - v[u][0][k].get<double>());
    }
    double mean = 0, ss = 0;
    for (double x : d) mean += x / static_cast<double>(d.size());
    for (double x : d) ss += (x - mean) * (x - mean);
    return std::pair{mean, std::sqrt(ss / static_cast<double>(d.size() - 1) / static_cast<double>(d.size()))};
  };
  // 200 ppm of 0.4 deg is 0.288 arcsec at the set point: stand C's calibrated angle differs by it.
  const double d_arcsec = 200e-6 * 0.4 * 3600;
  for (const char* q : {"angle_pitch_at_+0.4deg_arcsec", "angle_yaw_at_-0.4deg_arcsec"}) {
    const auto [mean, se] = c_minus_a(q);
    EXPECT_NEAR(std::abs(mean), d_arcsec, std::max(0.03, 4 * se)) << q << " (se " << se << ")";
    const auto& g = m["quantities"][q];
    // Stand means (0, 0, d): their SD is d / sqrt(3) = 0.166 arcsec, which AV must find (three
    // stands: two degrees of freedom, so loosely). EV is not bounded here: the runs share two
    // cores with the rest of ctest, and a loaded machine makes the emulated frames scatter more
    // (measured EV 0.064 arcsec alone, 0.097 under ctest -j2), which AV must not follow.
    EXPECT_GT(g["sd"]["av"].get<double>(), 0.5 * d_arcsec / std::sqrt(3.0)) << q;
    EXPECT_LT(g["sd"]["av"].get<double>(), 2.0 * d_arcsec / std::sqrt(3.0)) << q;
  }
  // Where the scale error cannot act (zero counts), AV is a fraction of that.
  for (const char* q : {"angle_pitch_at_+0.0deg_arcsec", "angle_yaw_at_+0.0deg_arcsec"}) {
    EXPECT_LT(m["quantities"][q]["sd"]["av"].get<double>(), 0.25 * d_arcsec / std::sqrt(3.0)) << q;
  }
  // At zero counts (near the null) the encoders' scale error does not act: no stand effect beyond the noise.
  const auto [null_mean, null_se] = c_minus_a("angle_pitch_at_+0.0deg_arcsec");
  EXPECT_LT(std::abs(null_mean), std::max(0.03, 4 * null_se)) << "se " << null_se;
  // An independent ANOVA of the same exported figures (numpy) agrees within 1 % (relative).
  const auto py = test::run_command({"/usr/bin/python3", (test::source_dir() / "tests" / "gen" / "msa_anova.py").string(),
                                     out.string()},
                                    tmp.path(), "numpy", 120);
  ASSERT_EQ(py.code, 0) << py.err;
  const auto mine = nlohmann::json::parse(py.out);
  for (const auto& [name, q] : m["quantities"].items()) {
    const auto& theirs = mine.at(name);
    for (const char* k : {"grr_percent_tv", "grr_percent_tolerance"}) {
      if (q[k].is_null()) continue;
      EXPECT_NEAR(q[k].get<double>(), theirs[k].get<double>(), 0.01 * theirs[k].get<double>()) << name << " " << k;
    }
    EXPECT_NEAR(q["sd"]["av"].get<double>(), theirs["av"].get<double>(), 0.01 * theirs["av"].get<double>() + 1e-12) << name;
  }
}

}  // namespace
}  // namespace fpss
