// for_each_sample_csv: the samples file row by row, with read_samples_csv's rows, checks and messages
// (line numbers included) whatever the chunk size.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "base/errors.h"
#include "calib/samples.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

const std::string kHeader = "time_s,phase,step,ref_pitch_arcsec,ref_yaw_arcsec,counts_alpha,counts_beta,extra\n";

std::string batch_error(const std::filesystem::path& p) {
  return test::error_of<InputError>([&] { read_samples_csv(p); });
}
std::string stream_error(const std::filesystem::path& p, size_t chunk) {
  return test::error_of<InputError>([&] { for_each_sample_csv(p, [](const Sample&) {}, chunk); });
}

TEST(SamplesStream, RowsAreThoseOfTheBatchReaderAtEveryChunkSize) {
  test::TempDir dir("samples-stream");
  std::string text = "# a comment before the header\n\n" + kHeader;
  for (int i = 0; i < 23; ++i) {
    text += std::to_string(0.1 * i) + "," + (i % 3 ? "offset" : "null") + "," + std::to_string(1 + i / 3) + "," +
            std::to_string(i) + ",0.5," + std::to_string(1000 + i) + ",-7,\"x,y\"\n";
    if (i == 7) text += "# a comment between rows\n\n";
  }
  const auto p = dir.write("rec.csv", text);
  const SampleTable t = read_samples_csv(p);
  for (size_t chunk : {1u, 2u, 3u, 5u, 4096u}) {
    std::vector<Sample> rows;
    EXPECT_EQ(for_each_sample_csv(p, [&](const Sample& s) { rows.push_back(s); }, chunk), t.size());
    ASSERT_EQ(rows.size(), t.size());
    for (size_t i = 0; i < t.size(); ++i) {
      EXPECT_EQ(rows[i].time_s, t.time_s[i]);
      EXPECT_EQ(rows[i].step, t.step[i]);
      EXPECT_EQ(rows[i].phase, t.phase[i]);
      EXPECT_EQ(rows[i].ref_pitch_arcsec, t.ref_pitch_arcsec[i]);
      EXPECT_EQ(rows[i].counts_alpha, t.counts_alpha[i]);
      EXPECT_EQ(rows[i].counts_beta, t.counts_beta[i]);
    }
  }
}

TEST(SamplesStream, MessagesNameTheSameLineAsTheBatchReader) {
  test::TempDir dir("samples-stream");
  const std::string good = "0,null,1,0,0,0,0,a\n0.1,null,1,0,0,0,0,a\n0.2,offset,2,5,0,40,0,a\n0.3,offset,2,5,0,40,0,a\n";
  const std::vector<std::string> bad = {
      "",                                                          // empty
      "# only a comment\n",                                        // no header
      "time_s,phase,step,ref_pitch_arcsec,ref_yaw_arcsec\n",       // missing columns
      kHeader + good + "0.4,null,3,0,abc,0,0,a\n",                 // not a number, 6th line
      kHeader + good + "0.1,null,3,0,0,0,0,a\n",                   // time backwards across a chunk edge
      kHeader + good + "# note\n0.5,null,1,0,0,0,0,a\n",           // step decreasing after a comment
      kHeader + good + "0.5,sideways,3,0,0,0,0,a\n",               // unknown phase
      kHeader + good + "0.5,null,3,0,0,0\n",                       // too few fields
      "# c\n" + kHeader + "0,null,1,0,0,0,0,a\n0,\"null,1,0,0,0,0,a\n",  // unterminated quote
  };
  for (size_t i = 0; i < bad.size(); ++i) {
    const auto p = dir.write("bad" + std::to_string(i) + ".csv", bad[i]);
    const std::string want = batch_error(p);
    ASSERT_FALSE(want.empty()) << i;
    for (size_t chunk : {1u, 2u, 3u, 4096u}) EXPECT_EQ(stream_error(p, chunk), want) << "case " << i << ", chunk " << chunk;
  }
  EXPECT_EQ(stream_error(dir / "missing.csv", 10), batch_error(dir / "missing.csv"));
}

}  // namespace
}  // namespace fpss
