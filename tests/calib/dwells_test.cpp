// Dwell averaging and null/offset pairing.
#include "calib/dwells.h"

#include <gtest/gtest.h>

#include <cmath>

#include "base/errors.h"

namespace fpss {
namespace {

void add(SampleTable& t, double time, Phase ph, int64_t step, double rp, double ry, double ca, double cb) {
  t.push_back(Sample{time, ph, step, rp, ry, ca, cb});
}

TEST(Dwells, AveragesNullAndOffsetRowsPerStepIgnoringSlews) {
  SampleTable t;
  add(t, 0.0, Phase::null, 1, 0.1, -0.1, 10, 20);
  add(t, 0.1, Phase::null, 1, 0.3, 0.1, 12, 22);
  add(t, 0.2, Phase::null, 1, 0.2, 0.0, 11, 24);
  add(t, 0.3, Phase::slew, 2, 50, 0, 400, 20);
  add(t, 0.4, Phase::move, 3, 90, 0, 800, 20);
  add(t, 0.5, Phase::offset, 4, 100.0, 0.5, 910, 21);
  add(t, 0.6, Phase::offset, 4, 102.0, 0.7, 912, 23);
  add(t, 0.9, Phase::null, 5, 0.0, 0.0, 11, 21);
  const auto d = average_dwells(t);
  ASSERT_EQ(d.size(), 3u);
  EXPECT_EQ(d[0].step, 1);
  EXPECT_EQ(d[0].phase, Phase::null);
  EXPECT_EQ(d[0].samples, 3u);
  EXPECT_DOUBLE_EQ(d[0].counts_alpha, 11);
  EXPECT_DOUBLE_EQ(d[0].counts_beta, 22);
  EXPECT_NEAR(d[0].ref_pitch_arcsec, 0.2, 1e-12);
  EXPECT_NEAR(d[0].sd_counts_alpha, 1.0, 1e-12);
  EXPECT_NEAR(d[0].sd_counts_beta, 2.0, 1e-12);
  EXPECT_NEAR(d[0].sd_ref_pitch_arcsec, 0.1, 1e-12);
  EXPECT_DOUBLE_EQ(d[0].t_start_s, 0.0);
  EXPECT_DOUBLE_EQ(d[0].t_end_s, 0.2);
  EXPECT_EQ(d[1].step, 4);
  EXPECT_EQ(d[1].phase, Phase::offset);
  EXPECT_DOUBLE_EQ(d[1].ref_pitch_arcsec, 101.0);
  EXPECT_DOUBLE_EQ(d[1].counts_alpha, 911.0);
  EXPECT_NEAR(d[1].sd_counts_alpha, std::sqrt(2.0), 1e-12);
  EXPECT_EQ(d[2].samples, 1u);
  EXPECT_EQ(d[2].sd_counts_alpha, 0.0);
}

TEST(Dwells, ScatterStaysExactAtLargeCounts) {
  SampleTable t;
  for (int i = 0; i < 1000; ++i) add(t, i, Phase::offset, 7, 1500.0, 0, 32000.0 + (i % 2 ? 0.3 : -0.3), -32000.0);
  const auto d = average_dwells(t);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_NEAR(d[0].counts_alpha, 32000.0, 1e-9);
  EXPECT_NEAR(d[0].sd_counts_alpha, 0.3 * std::sqrt(1000.0 / 999.0), 1e-9);
  EXPECT_EQ(d[0].sd_counts_beta, 0.0);
}

// Frames that repeat the frame before's two reference angles share its encoder reading: the
// reference's scatter is over readings, and the mean is worth n^2 / sum(m^2) readings.
TEST(Dwells, FramesSharingAnEncoderReadingCountItOnce) {
  SampleTable t;
  const double refs[6][2] = {{1.0, 2.0}, {1.0, 2.0}, {1.0, 2.0}, {1.2, 2.0}, {1.2, 2.0}, {1.4, 2.1}};
  for (int i = 0; i < 6; ++i) add(t, 0.1 * i, Phase::offset, 3, refs[i][0], refs[i][1], 100 + i % 2, 50);
  // One frame per reading, even when a coordinate repeats: both angles must agree.
  add(t, 1.0, Phase::null, 4, 0.0, 0.1, 0, 0);
  add(t, 1.1, Phase::null, 4, 0.0, 0.2, 0, 0);
  const auto d = average_dwells(t);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].samples, 6u);
  EXPECT_EQ(d[0].ref_readings, 3u);
  EXPECT_DOUBLE_EQ(d[0].ref_readings_eff, 36.0 / (9 + 4 + 1));
  EXPECT_NEAR(d[0].ref_pitch_arcsec, (3 * 1.0 + 2 * 1.2 + 1.4) / 6, 1e-12);  // the frames' mean
  EXPECT_NEAR(d[0].sd_ref_pitch_arcsec, 0.2, 1e-12);                       // over 1.0, 1.2, 1.4
  EXPECT_EQ(d[1].ref_readings, 2u);
  EXPECT_DOUBLE_EQ(d[1].ref_readings_eff, 2.0);
}

TEST(Dwells, AStepWithBothNullAndOffsetRowsIsADataError) {
  SampleTable t;
  t.origin = "rec.csv";
  add(t, 0, Phase::null, 3, 0, 0, 0, 0);
  add(t, 1, Phase::offset, 3, 100, 0, 900, 0);
  try {
    average_dwells(t);
    FAIL();
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("rec.csv: step 3 holds both null and offset rows"), std::string::npos)
        << e.what();
  }
}

std::vector<Dwell> dwells_of(const std::string& pattern) {
  std::vector<Dwell> v;
  int64_t step = 0;
  for (char c : pattern) {
    Dwell d;
    d.step = ++step;
    d.phase = c == 'N' ? Phase::null : Phase::offset;
    v.push_back(d);
  }
  return v;
}

TEST(Dwells, EachOffsetPairsWithTheNearestNullBeforeAndAfter) {
  const auto pairs = pair_dwells(dwells_of("NONOONO"));
  std::vector<std::tuple<size_t, size_t, bool>> got;
  for (const auto& p : pairs) got.emplace_back(p.null_index, p.offset_index, p.null_first);
  const std::vector<std::tuple<size_t, size_t, bool>> want = {
      {0, 1, true}, {2, 1, false}, {2, 3, true}, {2, 4, true}, {5, 3, false}, {5, 4, false}, {5, 6, true}};
  EXPECT_EQ(got, want);
}

TEST(Dwells, OffsetsBeforeTheFirstNullPairOnlyForward) {
  const auto pairs = pair_dwells(dwells_of("OON"));
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0].null_index, 2u);
  EXPECT_EQ(pairs[0].offset_index, 0u);
  EXPECT_FALSE(pairs[0].null_first);
  EXPECT_TRUE(pair_dwells(dwells_of("NNN")).empty());
}

}  // namespace
}  // namespace fpss
