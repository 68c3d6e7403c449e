// The one reduction: glitch frames are counted per axis and kept out of both axes' means, the
// detrended scatter removes a drift through a dwell, and a calibration file's rule redoes it exactly.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "base/errors.h"
#include "calib/reduction.h"

namespace fpss {
namespace {

// Null and offset dwells of `frames` frames each, whole counts with Gaussian noise (seeded); each
// dwell's counts drift by `drift_counts_per_s`. The spikes go on the listed (row, axis) places.
struct Recording {
  SampleTable t;
  std::vector<std::pair<size_t, int>> spikes;  // row, axis (0 alpha, 1 beta)
};

Recording make(int dwells, int frames, double noise_counts, double drift_counts_per_s, int spikes, uint64_t seed) {
  Recording r;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, noise_counts);
  double t = 0;
  for (int k = 0; k < dwells; ++k) {
    const bool null = k % 2 == 0;
    const double level = null ? 0 : 300.0 * (k / 2 + 1);
    for (int f = 0; f < frames; ++f, t += 0.02) {
      const double ramp = drift_counts_per_s * 0.02 * f;
      Sample s{t, null ? Phase::null : Phase::offset, k + 1, level * 0.11, -level * 0.05,
               std::round(level + ramp + g(rng)), std::round(-level * 0.5 + ramp + g(rng))};
      r.t.push_back(s);
    }
  }
  std::uniform_int_distribution<size_t> row(0, r.t.size() - 1);
  for (int i = 0; i < spikes; ++i) {
    const size_t at = row(rng);
    const int axis = i % 2;
    (axis == 0 ? r.t.counts_alpha : r.t.counts_beta)[at] += (i % 4 < 2 ? 400 : -400);
    r.spikes.push_back({at, axis});
  }
  return r;
}

TEST(Reduction, GlitchFramesAreCountedPerAxisAndLeftOutOfBothMeans) {
  const Recording rec = make(20, 50, 0.8, 0, 8, 11);
  const Recording clean = make(20, 50, 0.8, 0, 0, 11);
  const Reduction r = reduce(rec.t);
  EXPECT_EQ(r.outliers.frames, 1000u);
  EXPECT_EQ(r.outliers.alpha.outlier_frames, 4u);
  EXPECT_EQ(r.outliers.beta.outlier_frames, 4u);
  EXPECT_EQ(r.outliers.any.outlier_frames, 8u);
  EXPECT_DOUBLE_EQ(r.outliers.worst_share(), 4.0 / 1000.0);
  EXPECT_EQ(r.outliers.count_noise_source, "within-dwell scatter");
  ASSERT_TRUE(r.outliers.count_noise_counts);
  EXPECT_NEAR(*r.outliers.count_noise_counts, 0.8, 0.1);
  for (const auto& [row, axis] : rec.spikes) {
    EXPECT_TRUE(axis == 0 ? r.flags[row].alpha : r.flags[row].beta) << row;
  }
  // A spike is off by 400 counts: in a 50-frame mean it would move it by 8. Without them, the
  // means are the clean recording's means of the same frames less the glitched ones.
  const Reduction c = reduce(clean.t);
  ASSERT_EQ(r.dwells.size(), c.dwells.size());
  for (size_t i = 0; i < r.dwells.size(); ++i) {
    EXPECT_NEAR(r.dwells[i].counts_alpha, c.dwells[i].counts_alpha, 0.2) << i;
    EXPECT_NEAR(r.dwells[i].counts_beta, c.dwells[i].counts_beta, 0.2) << i;
    EXPECT_LT(r.dwells[i].sd_counts_alpha, 1.5) << i;
    EXPECT_EQ(r.dwells[i].frames(), 50u);
  }
  EXPECT_EQ(c.outliers.any.outlier_frames, 0u);
}

TEST(Reduction, TheFileRuleRedoesTheSameReductionAndRoundTrips) {
  const Recording rec = make(12, 20, 0.5, 0, 6, 5);
  const Reduction first = reduce(rec.t);
  const nlohmann::json j = nlohmann::json::parse(first.outliers.to_json().dump());
  EXPECT_EQ(j["pitch"]["outlier_frames"], first.outliers.alpha.outlier_frames);
  EXPECT_DOUBLE_EQ(j["yaw"]["share"].get<double>(), first.outliers.beta.share(first.outliers.frames));
  nlohmann::json extra = {{"outliers", j}};
  const ReductionOptions o = reduction_options_of(extra, "cal.json");
  EXPECT_EQ(o.count_noise_counts, first.outliers.count_noise_counts);  // given now, not estimated
  const Reduction again = reduce(rec.t, o);
  ASSERT_EQ(again.flags.size(), first.flags.size());
  for (size_t i = 0; i < again.flags.size(); ++i) {
    EXPECT_EQ(again.flags[i].alpha, first.flags[i].alpha);
    EXPECT_EQ(again.flags[i].beta, first.flags[i].beta);
  }
  ASSERT_EQ(again.dwells.size(), first.dwells.size());
  for (size_t i = 0; i < again.dwells.size(); ++i) EXPECT_EQ(again.dwells[i].counts_alpha, first.dwells[i].counts_alpha);
  // A block that contradicts itself is refused, naming the file.
  extra["outliers"]["pitch"]["outlier_frames"] = 1000000;
  try {
    reduction_options_of(extra, "cal.json");
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cal.json"), std::string::npos);
  }
  // No block (an imported set): the default rule.
  EXPECT_FALSE(reduction_options_of(nlohmann::json::object(), "x").count_noise_counts);
}

// The SD of v about its least-squares line in t (n - 2 degrees of freedom), computed directly.
double line_sd(const std::vector<double>& t, const std::vector<double>& v) {
  const double n = static_cast<double>(v.size());
  double tm = 0, vm = 0;
  for (size_t i = 0; i < v.size(); ++i) tm += t[i] / n, vm += v[i] / n;
  double stt = 0, stv = 0;
  for (size_t i = 0; i < v.size(); ++i) stt += (t[i] - tm) * (t[i] - tm), stv += (t[i] - tm) * (v[i] - vm);
  double rss = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    const double r = v[i] - vm - stv / stt * (t[i] - tm);
    rss += r * r;
  }
  return std::sqrt(rss / (n - 2));
}

TEST(Reduction, DetrendedScatterRemovesADriftThroughTheDwell) {
  // 100 frames over 2 s, drifting 10 counts per second: 20 counts end to end, about 5.8 sd.
  const Recording rec = make(4, 100, 1.0, 10.0, 0, 3);
  const Reduction r = reduce(rec.t);
  ASSERT_EQ(r.dwells.size(), 4u);
  for (size_t k = 0; k < r.dwells.size(); ++k) {
    const Dwell& d = r.dwells[k];
    const auto at = [&](const std::vector<double>& col) {
      return std::vector<double>(col.begin() + static_cast<long>(100 * k), col.begin() + static_cast<long>(100 * (k + 1)));
    };
    EXPECT_NEAR(d.sd_detrended_counts_alpha, line_sd(at(rec.t.time_s), at(rec.t.counts_alpha)), 1e-9);
    EXPECT_NEAR(d.sd_detrended_counts_beta, line_sd(at(rec.t.time_s), at(rec.t.counts_beta)), 1e-9);
    EXPECT_GT(d.sd_counts_alpha, 4.0);
    // The noise with its rounding, sqrt(1 + 1/12) = 1.04, within 3 of its sd 1.04 / sqrt(2 x 98).
    EXPECT_NEAR(d.sd_detrended_counts_alpha, 1.04, 0.23);
    EXPECT_NEAR(d.sd_detrended_counts_beta, 1.04, 0.23);
  }
}

}  // namespace
}  // namespace fpss
