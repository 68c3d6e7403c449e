// The streaming (recursive least squares) estimator: live estimates and agreement with the batch fit.
#include "calib/streaming.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "base/errors.h"
#include "calib/reduction.h"
#include "fixtures/recording.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

SampleTable recording(const CoefficientSet& truth, uint64_t seed = 3) {
  BenchConfig cfg = default_bench_config();
  cfg.truth = truth;
  cfg.seed = seed;
  return simulate_null_offset(cfg, GridPlan{});
}

CalibrationOptions one_thread() {
  CalibrationOptions o;
  o.threads = 1;
  return o;
}

TEST(Streaming, EstimatesConvergeAsPairsArrive) {
  const auto truth = load_published("a-2-fpss2");
  const SampleTable t = recording(truth);
  const auto dwells = average_dwells(t);
  StreamingCalibrator s(one_thread());
  EXPECT_FALSE(s.current().valid);
  size_t first_valid = 0;
  std::vector<double> rms;
  for (const auto& d : dwells) {
    s.add_dwell(d);
    const auto e = s.current();
    if (!e.valid) {
      EXPECT_FALSE(e.why_not.empty());
      continue;
    }
    if (first_valid == 0) first_valid = e.pairs;
    rms.push_back(std::max(e.rms_pitch_arcsec, e.rms_yaw_arcsec));
  }
  // Pitch offsets come first: the estimate needs the yaw offsets too before it is valid.
  EXPECT_GT(first_valid, 28u);
  ASSERT_FALSE(rms.empty());
  EXPECT_EQ(s.pairs(), 56u);
  const auto e = s.current();
  ASSERT_TRUE(e.valid);
  // The best grid node alone (no refinement) is already close to the noise and the truth.
  std::printf("after %zu pairs: grid-node rms %.3f/%.3f arcsec, max from truth %.3f/%.3f arcsec\n", e.pairs,
              e.rms_pitch_arcsec, e.rms_yaw_arcsec,
              compare_transfer(e.alpha, truth.alpha, -13000, 13000).max_abs_arcsec,
              compare_transfer(e.beta, truth.beta, -13000, 13000).max_abs_arcsec);
  EXPECT_LT(e.rms_pitch_arcsec, 0.1);
  EXPECT_LT(e.rms_yaw_arcsec, 0.1);
  EXPECT_LT(compare_transfer(e.alpha, truth.alpha, -13000, 13000).max_abs_arcsec, 0.3);
  EXPECT_LT(compare_transfer(e.beta, truth.beta, -13000, 13000).max_abs_arcsec, 0.3);
}

TEST(Streaming, FinishAgreesWithTheBatchFitWhicheverWayTheDataComeIn) {
  const auto truth = load_published("a-4-fpss1");
  const SampleTable t = recording(truth, 11);
  const CalibrationReport batch = calibrate(t, one_thread());

  StreamingCalibrator by_sample(one_thread());
  for (size_t i = 0; i < t.size(); ++i) by_sample.add_sample(t.row(i));
  const CalibrationReport a = by_sample.finish();

  // Pairs fed directly, as a procedure that forms them itself would.
  StreamingCalibrator by_pair(one_thread());
  const auto dwells = average_dwells(t);
  for (const auto& p : pair_dwells(dwells)) by_pair.add_pair(dwells[p.null_index], dwells[p.offset_index]);
  for (const auto& d : dwells) if (d.phase == Phase::null) by_pair.add_null(d);
  const CalibrationReport b = by_pair.finish();

  for (const CalibrationReport* r : {&a, &b}) {
    EXPECT_EQ(r->pairs, batch.pairs);
    EXPECT_LT(compare_transfer(r->pitch.coeffs, batch.pitch.coeffs, batch.pitch.counts_range[0],
                               batch.pitch.counts_range[1]).max_abs_arcsec, 0.1);
    EXPECT_LT(compare_transfer(r->yaw.coeffs, batch.yaw.coeffs, batch.yaw.counts_range[0],
                               batch.yaw.counts_range[1]).max_abs_arcsec, 0.1);
    EXPECT_EQ(r->pitch.residuals.points, batch.pitch.residuals.points);
  }
  EXPECT_EQ(a.samples, t.size());
  EXPECT_EQ(a.null_dwells, batch.null_dwells);
  EXPECT_EQ(a.offset_dwells, batch.offset_dwells);
}

// The live path (rows one at a time, as a run records them) with glitch frames: they stay out of
// its dwells as they stay out of the batch fit's, and its estimate is as good as on clean data.
TEST(Streaming, GlitchFramesStayOutOfTheLiveEstimate) {
  const auto truth = load_published("a-6-fpss1");
  SampleTable t = recording(truth, 23);
  size_t spikes = 0;
  for (size_t i = 40; i < t.size(); i += 31) {
    if (t.phase[i] == Phase::slew || t.phase[i] == Phase::move) continue;
    (spikes % 2 ? t.counts_beta : t.counts_alpha)[i] += 400;
    ++spikes;
  }
  ASSERT_GT(spikes, 5u);
  StreamingCalibrator live(one_thread());
  for (size_t i = 0; i < t.size(); ++i) live.add_sample(t.row(i));
  const auto e = live.current();
  ASSERT_TRUE(e.valid) << e.why_not;
  EXPECT_LT(e.rms_pitch_arcsec, 0.1);
  EXPECT_LT(e.rms_yaw_arcsec, 0.1);
  const CalibrationReport a = live.finish();
  const CalibrationReport batch = calibrate(t, one_thread());
  EXPECT_EQ(a.outliers.any.outlier_frames, spikes);
  EXPECT_EQ(batch.outliers.any.outlier_frames, spikes);
  EXPECT_LT(compare_transfer(a.pitch.coeffs, truth.alpha, a.pitch.counts_range[0], a.pitch.counts_range[1]).max_abs_arcsec,
            0.3);
}

TEST(Streaming, AFileCalibratedRowByRowEqualsTheBatchCalibration) {
  const auto truth = load_published("a-6-fpss1");
  SampleTable t = recording(truth, 21);
  // Spikes in a few frames of either axis (the outlier rule must find the same frames both ways).
  for (size_t i = 7; i < t.size(); i += 97) {
    if (t.phase[i] == Phase::slew || t.phase[i] == Phase::move) continue;
    (i % 2 ? t.counts_alpha[i] : t.counts_beta[i]) += (i % 3 ? 40.0 : -150.0);
  }
  test::TempDir dir("streaming");
  const auto path = dir / "rec.csv";
  write_samples_csv(path, t);
  const SampleTable back = read_samples_csv(path);
  for (bool given_noise : {false, true}) {
    CalibrationOptions o = one_thread();
    if (given_noise) o.count_noise_counts = 0.3;
    const CalibrationReport batch = calibrate(back, o);
    const CalibrationReport stream = calibrate_csv(path, o);
    EXPECT_GT(batch.outliers.any.outlier_frames, 0u);
    EXPECT_EQ(stream.outliers.any.outlier_frames, batch.outliers.any.outlier_frames);
    // One reduction: the file path counts the same frames per axis, under the same rule noise.
    EXPECT_EQ(stream.outliers.alpha.outlier_frames, batch.outliers.alpha.outlier_frames);
    EXPECT_EQ(stream.outliers.beta.outlier_frames, batch.outliers.beta.outlier_frames);
    EXPECT_EQ(stream.outliers.frames, batch.outliers.frames);
    ASSERT_TRUE(stream.outliers.count_noise_counts && batch.outliers.count_noise_counts);
    EXPECT_DOUBLE_EQ(*stream.outliers.count_noise_counts, *batch.outliers.count_noise_counts);
    EXPECT_EQ(stream.outliers.count_noise_source, batch.outliers.count_noise_source);
    EXPECT_EQ(stream.samples, batch.samples);
    EXPECT_EQ(stream.pairs, batch.pairs);
    EXPECT_EQ(stream.null_dwells, batch.null_dwells);
    // The same dwells and the same fit: equal to rounding.
    for (int i = 0; i < 8; ++i) {
      EXPECT_NEAR(stream.pitch.coeffs[i], batch.pitch.coeffs[i], 1e-9 * std::abs(batch.pitch.coeffs[i]) + 1e-15) << i;
      EXPECT_NEAR(stream.yaw.coeffs[i], batch.yaw.coeffs[i], 1e-9 * std::abs(batch.yaw.coeffs[i]) + 1e-15) << i;
    }
    EXPECT_EQ(stream.pitch.noise.count_noise_source, batch.pitch.noise.count_noise_source);
    EXPECT_NEAR(stream.pitch.angle_sigma_max_arcsec, batch.pitch.angle_sigma_max_arcsec, 1e-9);
  }
  // What cannot be calibrated says so as the batch calibrator does.
  SampleTable nulls;
  for (size_t i = 0; i < t.size(); ++i)
    if (t.phase[i] == Phase::null) nulls.push_back(t.row(i));
  write_samples_csv(dir / "nulls.csv", nulls);
  const std::string m = test::error_of<DataError>([&] { calibrate_csv(dir / "nulls.csv", one_thread()); });
  EXPECT_NE(m.find("no offset dwells"), std::string::npos) << m;
}

// Settling inside every fourth dwell (counts decaying from 40 counts with a time constant of 6 frames, the
// fastest the catalogue draws: tau 0.3 s at 20 Hz; both axes), at the count noise the stand knows: the one
// rule judges a frame against the running median of its step, which follows the decay, so the
// batch reduction, the live screen and the file path all flag the injected spikes and nothing
// else. Against the whole step's median (the rule before) the decay's early frames were outliers.
TEST(Streaming, ASettlingDecayIsNoOutlierInAnyPath) {
  const auto truth = load_published("a-6-fpss1");
  GridPlan g;
  g.samples_per_dwell = 25;
  BenchConfig cfg = default_bench_config();
  cfg.truth = truth;
  cfg.seed = 31;
  SampleTable t = simulate_null_offset(cfg, g);
  size_t spikes = 0;
  for (size_t i = 0, j = 0; i < t.size(); ++i) {
    j = (i > 0 && t.step[i] == t.step[i - 1]) ? j + 1 : 0;
    const double decay = t.step[i] % 4 == 0 ? std::round(40.0 * std::exp(-static_cast<double>(j) / 6.0)) : 0.0;
    t.counts_alpha[i] += decay;
    t.counts_beta[i] -= decay;
    if (i % 53 == 17) {
      (spikes % 2 ? t.counts_beta : t.counts_alpha)[i] += 300;
      ++spikes;
    }
  }
  ASSERT_GT(spikes, 5u);
  // The rule before (the step's median) took the decay's early frames for outliers: the test can
  // tell the two apart.
  OutlierRule step_median;
  step_median.min_sigma = count_outlier_floor(0.3);
  EXPECT_GT(flag_outliers(t.counts_alpha, t.step, step_median).count, static_cast<int64_t>(spikes));
  ReductionOptions ro;
  ro.count_noise_counts = 0.3;
  const Reduction r = reduce(t, ro);
  EXPECT_EQ(r.outliers.any.outlier_frames, spikes);
  CalibrationOptions o = one_thread();
  o.count_noise_counts = 0.3;
  StreamingCalibrator live(o);
  for (size_t i = 0; i < t.size(); ++i) live.add_sample(t.row(i));
  EXPECT_EQ(live.finish().outliers.any.outlier_frames, spikes);
  test::TempDir dir("streaming-settling");
  write_samples_csv(dir / "rec.csv", t);
  EXPECT_EQ(calibrate_csv(dir / "rec.csv", o).outliers.any.outlier_frames, spikes);
  EXPECT_EQ(calibrate(t, o).outliers.any.outlier_frames, spikes);
}

TEST(Streaming, OnlyTheDifferencesMethod) {
  CalibrationOptions o;
  o.method = Method::absolute;
  EXPECT_THROW(StreamingCalibrator{o}, std::invalid_argument);
}

}  // namespace
}  // namespace fpss
