// Helpers of the `fpss-stand run` end-to-end tests: run folders, recorded points, distance to the truth.
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <nlohmann/json.hpp>

#include "calib/calibrator.h"
#include "calib/coefficients.h"
#include "calib/samples.h"
#include "stand/catalogue/sqlite_catalogue.h"
#include "procedures/procedure.h"
#include "procedures/recorder.h"
#include "tests/procedures/run_util.h"

namespace fpss::runtest {

namespace fs = std::filesystem;

inline std::string proc(const char* name) { return (test::source_dir() / "procedures" / name).string(); }

inline fs::path only_run(const fs::path& runs) {
  const auto dirs = test::run_dirs(runs);
  EXPECT_EQ(dirs.size(), 1u);
  return dirs.empty() ? fs::path() : dirs.front();
}

inline nlohmann::json run_json(const fs::path& dir) { return read_json_file(dir / "run.json"); }
// The catalogue's id of a run: run.json's run_id (a UUIDv7), not the folder's name.
inline std::string run_id_of(const fs::path& dir) { return run_json(dir).at("run_id").get<std::string>(); }

// A point's identity and measurement, as recorded.
struct PointRec {
  Phase phase;
  double target_pitch, target_yaw;
  size_t rows = 0;
  double mean_alpha = 0, mean_beta = 0;
};

inline std::map<int64_t, PointRec> points_of(const SampleTable& t) {
  std::map<int64_t, PointRec> m;
  const auto tp = t.numeric_column("target_pitch_arcsec");
  const auto ty = t.numeric_column("target_yaw_arcsec");
  for (size_t i = 0; i < t.size(); ++i) {
    auto& p = m[t.step[i]];
    p.phase = t.phase[i];
    p.target_pitch = tp[i];
    p.target_yaw = ty[i];
    p.mean_alpha += t.counts_alpha[i];
    p.mean_beta += t.counts_beta[i];
    ++p.rows;
  }
  for (auto& [s, p] : m) {
    p.mean_alpha /= static_cast<double>(p.rows);
    p.mean_beta /= static_cast<double>(p.rows);
  }
  return m;
}

// Steps are contiguous 1..n and each appears in one block (no duplicate, no gap).
inline void expect_contiguous_points(const SampleTable& t, int64_t n) {
  ASSERT_FALSE(t.empty());
  std::set<int64_t> seen;
  int64_t prev = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    if (t.step[i] != prev) {
      EXPECT_EQ(t.step[i], prev + 1) << "row " << i;
      EXPECT_TRUE(seen.insert(t.step[i]).second) << "step " << t.step[i] << " recorded twice";
      prev = t.step[i];
    }
  }
  EXPECT_EQ(prev, n);
}

// How far a calibration is from the emulator's truth over the count range the recording covered.
inline std::pair<double, double> distance_to_truth(const fs::path& run, const CoefficientSet& truth) {
  const CoefficientSet fit = load_coefficients(run / "calibration.json");
  const SampleTable t = read_samples_csv(run / "samples.csv");
  const auto [alo, ahi] = std::minmax_element(t.counts_alpha.begin(), t.counts_alpha.end());
  const auto [blo, bhi] = std::minmax_element(t.counts_beta.begin(), t.counts_beta.end());
  return {compare_transfer(fit.alpha, truth.alpha, *alo, *ahi).max_abs_arcsec,
          compare_transfer(fit.beta, truth.beta, *blo, *bhi).max_abs_arcsec};
}

}  // namespace fpss::runtest
