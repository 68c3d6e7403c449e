// The samples CSV (the stand's recording format): reading, writing, appending, and malformed files.
#include "calib/samples.h"

#include <sys/stat.h>

#include <gtest/gtest.h>

#include <limits>

#include <cmath>
#include <filesystem>

#include "base/errors.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;

const char* kHeader = "time_s,phase,step,ref_pitch_arcsec,ref_yaw_arcsec,counts_alpha,counts_beta\n";

std::string error_of(const std::string& text) {
  return test::error_of<InputError>([&] { parse_samples_csv(text, "rec.csv"); });
}

// A text parse_samples_csv refuses, and a part of the message it must give.
struct Refused {
  std::string text;
  const char* says;
};

void expect_refused(std::initializer_list<Refused> cases) {
  for (const auto& c : cases) {
    const std::string m = error_of(c.text);
    EXPECT_NE(m.find(c.says), std::string::npos) << m;
  }
}

// The same for rows under the required columns' header.
void expect_rows_refused(std::initializer_list<Refused> cases) {
  for (const auto& c : cases) expect_refused({{kHeader + c.text, c.says}});
}

using test::TempDir;

TEST(Samples, ColumnsInAnyOrderExtrasKept) {
  const std::string text =
      "# a comment before the header\n"
      "counts_beta,note,phase,time_s,step,ref_yaw_arcsec,counts_alpha,ref_pitch_arcsec,temperature_c\n"
      "-12,\"a, quoted\",null,0.5,1,0.01,3,-0.02,20.5\r\n"
      "\n"
      "1000.5,,offset,1.0,2,120.25,-7,+0.5,\n";
  const SampleTable t = parse_samples_csv(text, "mem");
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t.phase[0], Phase::null);
  EXPECT_EQ(t.phase[1], Phase::offset);
  EXPECT_EQ(t.step[1], 2);
  EXPECT_DOUBLE_EQ(t.counts_beta[1], 1000.5);
  EXPECT_DOUBLE_EQ(t.ref_pitch_arcsec[1], 0.5);
  EXPECT_EQ(t.extra_names(), (std::vector<std::string>{"note", "temperature_c"}));
  EXPECT_EQ(t.extra_column("note")[0], "a, quoted");
  const auto temp = t.numeric_column("temperature_c");
  EXPECT_EQ(temp[0], 20.5);
  EXPECT_TRUE(std::isnan(temp[1]));  // empty cell
  EXPECT_THROW(t.numeric_column("note"), InputError);  // "a, quoted" is not a number
}

TEST(Samples, MalformedRowsNameLineAndColumn) {
  expect_refused({
      {"time_s,phase,step,ref_pitch_arcsec,ref_yaw_arcsec,counts_alpha\n0,null,1,0,0,0\n",
       "rec.csv:1: missing required column \"counts_beta\""},
      {"time_s,time_s,phase,step,ref_pitch_arcsec,ref_yaw_arcsec,counts_alpha,counts_beta\n",
       "column \"time_s\" appears twice"},
      {"", "empty file"},
  });
  expect_rows_refused({
      {"0,null,1,0,0,0,0\n0.1,null,1,0,abc,0,0\n",
       "rec.csv:3: column \"ref_yaw_arcsec\": expected a finite number, got \"abc\""},
      {"0,null,1,0,0,inf,0\n", "rec.csv:2: column \"counts_alpha\": expected a finite number, got \"inf\""},
      {"0,null,1,0,0,0,nan\n", "column \"counts_beta\": expected a finite number"},
      {"0,sideways,1,0,0,0,0\n",
       "rec.csv:2: column \"phase\": expected null, offset, slew or move, got \"sideways\""},
      {"0,null,1.5,0,0,0,0\n", "column \"step\": expected an integer"},
      {"1.0,null,1,0,0,0,0\n0.5,null,1,0,0,0,0\n", "rec.csv:3: column \"time_s\": time goes backwards"},
      {"0,null,2,0,0,0,0\n1,null,1,0,0,0,0\n", "rec.csv:3: column \"step\": step decreases"},
      {"0,null,1,0,0,0\n", "rec.csv:2: expected 7 fields as in the header, got 6"},
      {"0,\"null,1,0,0,0,0\n", "rec.csv:2: unterminated quote"},
  });

  TempDir dir("samples");
  try {
    read_samples_csv(dir / "absent.csv");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot open samples file"), std::string::npos);
  }
}

TEST(Samples, WriteReadRoundTripIsExact) {
  SampleTable t;
  t.add_extra_column("temperature_c");
  t.push_back({0.1, Phase::null, 1, 0.1 + 0.2, -1e-7, 3, -4}, {"20.25"});
  t.push_back({0.3, Phase::offset, 2, 1512.0000001, 0.0, 13777.5, -1}, {""});
  t.push_back({0.4, Phase::slew, 3, 1.0 / 3.0, 2.0 / 3.0, -16000, 16000}, {"x,y"});
  TempDir dir("samples");
  const auto p = dir / "rec.csv";
  write_samples_csv(p, t);
  const SampleTable r = read_samples_csv(p);
  EXPECT_EQ(r.time_s, t.time_s);
  EXPECT_EQ(r.phase, t.phase);
  EXPECT_EQ(r.step, t.step);
  EXPECT_EQ(r.ref_pitch_arcsec, t.ref_pitch_arcsec);
  EXPECT_EQ(r.ref_yaw_arcsec, t.ref_yaw_arcsec);
  EXPECT_EQ(r.counts_alpha, t.counts_alpha);
  EXPECT_EQ(r.counts_beta, t.counts_beta);
  EXPECT_EQ(r.extra_column("temperature_c"), t.extra_column("temperature_c"));
  EXPECT_EQ(r.origin, p.string());
}

// A recorder's provenance is held as numbers (no text per cell in memory) and written as the
// same text a text column would hold: the file and the table in memory are one recording.
TEST(Samples, NumericColumnsHoldNumbersAndWriteTheSameText) {
  SampleTable t;
  t.add_numeric_column("gimbal_pitch_arcsec");
  t.add_extra_column("note");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  t.push_back({0.1, Phase::null, 1, 0, 0, 3, -4}, std::vector<double>{0.1 + 0.2, 7});
  t.push_back({0.2, Phase::null, 1, 0, 0, 3, -4}, std::vector<double>{nan, nan});
  t.push_back({0.3, Phase::null, 1, 0, 0, 3, -4}, std::vector<std::string>{"-12.5", "a, b"});
  EXPECT_EQ(t.numeric_column("gimbal_pitch_arcsec")[0], 0.1 + 0.2);
  EXPECT_TRUE(std::isnan(t.numeric_column("gimbal_pitch_arcsec")[1]));
  EXPECT_EQ(t.extra_column("gimbal_pitch_arcsec"), (std::vector<std::string>{"0.30000000000000004", "", "-12.5"}));
  EXPECT_EQ(t.extra_column("note"), (std::vector<std::string>{"7", "", "a, b"}));
  EXPECT_THROW(t.push_back({0.4, Phase::null, 1, 0, 0, 3, -4}, std::vector<std::string>{"x", ""}), InputError);
  TempDir dir("samples");
  write_samples_csv(dir / "rec.csv", t);
  const SampleTable r = read_samples_csv(dir / "rec.csv");
  const auto a = r.numeric_column("gimbal_pitch_arcsec"), b = t.numeric_column("gimbal_pitch_arcsec");
  ASSERT_EQ(a.size(), 3u);
  EXPECT_EQ(a[0], b[0]);
  EXPECT_TRUE(std::isnan(a[1]));
  EXPECT_EQ(a[2], b[2]);
  EXPECT_EQ(r.extra_column("note"), t.extra_column("note"));
  // The rows up to a step keep every column with its type (what a computation step is handed).
  t.push_back({0.4, Phase::offset, 2, 0, 0, 5, 6}, std::vector<double>{1.5, 2});
  const SampleTable head = t.up_to_step(1);
  ASSERT_EQ(head.size(), 3u);
  EXPECT_EQ(head.extra_names(), t.extra_names());
  EXPECT_EQ(head.numeric_column("gimbal_pitch_arcsec")[0], 0.1 + 0.2);
  EXPECT_EQ(head.extra_column("note")[2], "a, b");
  EXPECT_EQ(t.up_to_step(2).size(), 4u);
}

TEST(Samples, WriterAppendsAfterAMatchingHeaderOnly) {
  TempDir dir("samples");
  const auto p = dir / "rec.csv";
  {
    SamplesCsvWriter w(p, {"temperature_c"});
    w.append({0, Phase::null, 1, 0, 0, 1, 2}, {"20"});
    w.sync();
    EXPECT_EQ(w.rows_written(), 1u);
  }
  {
    SamplesCsvWriter w(p, {"temperature_c"});
    EXPECT_EQ(w.rows_written(), 1u);  // counted what was there
    w.append({1, Phase::offset, 2, 10, 0, 90, 2}, {"21"});
  }
  const SampleTable t = read_samples_csv(p);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t.phase[1], Phase::offset);
  EXPECT_EQ(t.extra_column("temperature_c")[1], "21");
  EXPECT_THROW(SamplesCsvWriter(p, {}), InputError);  // different header: refuse to append
}

TEST(Samples, PhaseNamesRoundTrip) {
  for (Phase p : {Phase::null, Phase::offset, Phase::slew, Phase::move}) {
    EXPECT_EQ(parse_phase(to_string(p)), p);
  }
  EXPECT_FALSE(parse_phase("NULL").has_value());
}

TEST(Samples, ByteOrderMarkAccepted) {
  const SampleTable t = parse_samples_csv("\xEF\xBB\xBF" + std::string(kHeader) + "0,null,1,0,0,3,4\n", "bom.csv");
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(t.counts_beta[0], 4);
  EXPECT_TRUE(t.extra_names().empty());  // the mark is not part of the first column's name
}

TEST(Samples, OverflowingValuesNameFileRowAndColumn) {
  expect_rows_refused({
      {"0,null,1,0,0,0,0\n1,offset,2,1e308,0,0,0\n",
       "rec.csv:3: column \"ref_pitch_arcsec\": 1e308 is beyond +-648000"},
      {"0,null,1,0,1e400,0,0\n", "rec.csv:2: column \"ref_yaw_arcsec\": expected a finite number, got \"1e400\""},
      {"1e300,null,1,0,0,0,0\n", "rec.csv:2: column \"time_s\": 1e300 is beyond"},
      {"0,null,1,0,0,-1e7,0\n", "rec.csv:2: column \"counts_alpha\": -1e7 is beyond +-1e+06"},
      {"0,null,99999999999999999999,0,0,0,0\n", "rec.csv:2: column \"step\": expected an integer"},
  });
}

TEST(Samples, WhatIsNotARegularFileIsRefusedNotRead) {
  TempDir d;
  const fs::path fifo = d / "rec.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const fs::path& p : {d.path(), fs::path("/dev/zero"), fifo}) {
    const std::string m = test::error_of<InputError>([&] { read_samples_csv(p); });
    EXPECT_NE(m.find(p.string() + ": not a regular file"), std::string::npos) << m;
  }
}

TEST(Samples, WriterLeavesNoPartialFileOnAFullDisk) {
  test::SmallTmpfs disk("64k");
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (needs root)";
  SampleTable t;
  for (int i = 0; i < 5000; ++i) t.push_back(Sample{i * 0.01, Phase::null, i, 1.25, -2.5, 100.5, -200.25});
  const fs::path out = disk / "rec.csv";
  const std::string m = test::error_of<std::runtime_error>([&] { write_samples_csv(out, t); });
  EXPECT_NE(m.find("rec.csv: write failed: No space left on device"), std::string::npos) << m;
  EXPECT_TRUE(fs::is_empty(disk.path()));  // neither a truncated CSV nor a temporary file
}

TEST(Samples, AppendingWriterNeverFollowsASymlink) {
  TempDir d;
  const fs::path victim = d.write("victim.txt", "");  // empty: the writer would write its header there
  fs::create_symlink(victim, d / "samples.csv");
  const std::string m = test::error_of<std::runtime_error>([&] { SamplesCsvWriter w(d / "samples.csv", {}); });
  EXPECT_NE(m.find("samples.csv: cannot open for append"), std::string::npos) << m;
  EXPECT_EQ(test::read_file(victim), "");
}

}  // namespace
}  // namespace fpss
