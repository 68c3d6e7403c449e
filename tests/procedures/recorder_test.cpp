// The run recorder on real files: synced points, the journal, and the cut of a torn point on resume.
#include <gtest/gtest.h>

#include <cmath>

#include "base/errors.h"
#include "calib/samples.h"
#include "procedures/align.h"
#include "procedures/recorder.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

using test::TempDir;
namespace fs = std::filesystem;

std::vector<RecordedRow> point_rows(int64_t point, int n, double t0) {
  std::vector<RecordedRow> rows;
  for (int i = 0; i < n; ++i) {
    RecordedRow r;
    r.sample = Sample{t0 + 0.02 * i, point % 2 ? Phase::offset : Phase::null, point + 1, 10.0 * point, -5.0 * point,
                      100.0 + point, -200.0 - i};
    r.sensor_time_s = 100 + t0 + 0.02 * i;
    r.frame_seq = static_cast<uint16_t>(point * 10 + i);
    r.sensor_status = 7;
    r.temperature_c = i == 0 ? std::nan("") : 20.5;
    r.attempt = 1;
    r.session = 1;
    rows.push_back(r);
  }
  return rows;
}

TEST(Recorder, PointsAreDurableAndReadableInTheSamplesContract) {
  TempDir tmp("recorder");
  const fs::path dir = tmp / "run";
  {
    RunRecorder rec(dir);
    EXPECT_EQ(rec.next_point(), 0);
    for (int64_t p = 0; p < 4; ++p) rec.append_point(p, point_rows(p, 3, p * 1.0), 1, 1);
    EXPECT_EQ(rec.next_point(), 4);
    EXPECT_EQ(rec.rows(), 12u);
    // Out of order is a programming error, not data.
    EXPECT_THROW(rec.append_point(7, point_rows(7, 1, 9), 1, 1), std::logic_error);
  }
  const SampleTable t = read_samples_csv(dir / "samples.csv");
  ASSERT_EQ(t.size(), 12u);
  EXPECT_EQ(t.step.front(), 1);
  EXPECT_EQ(t.step.back(), 4);
  EXPECT_EQ(t.phase[3], Phase::offset);
  for (const auto& c : recorder_extra_columns()) EXPECT_TRUE(t.has_column(c)) << c;
  EXPECT_EQ(t.extra_column("temperature_c")[0], "");  // no answer: an empty cell, not a made-up value
  EXPECT_EQ(t.extra_column("temperature_c")[1], "20.5");
  const auto journal = RunRecorder::read_journal(dir / "points.jsonl");
  ASSERT_EQ(journal.size(), 4u);
  EXPECT_EQ(journal.back().point, 3);
  EXPECT_EQ(journal.back().step, 4);
  EXPECT_EQ(journal.back().bytes, fs::file_size(dir / "samples.csv"));
  EXPECT_DOUBLE_EQ(journal.back().last_time_s, 3.04);
  // The file numbers points from 1, as the step column, the logs and the report do.
  const std::string text = test::read_file(dir / "points.jsonl");
  EXPECT_NE(text.find("\"point\":1,\"rows\":3,\"session\":1,\"step\":1,"), std::string::npos) << text;
  EXPECT_NE(text.find("\"point\":4,\"rows\":3,\"session\":1,\"step\":4,"), std::string::npos) << text;
  EXPECT_EQ(text.find("\"point\":0,"), std::string::npos) << text;
}

TEST(Recorder, AJournalOfAnEarlierVersionNumberedFromZeroStillResumes) {
  TempDir tmp("recorder-legacy");
  const fs::path dir = tmp / "run";
  fs::create_directories(dir);
  test::write_file(dir / "points.jsonl",
                   "{\"point\":0,\"step\":1,\"rows\":1,\"bytes\":10,\"last_time_s\":0}\n"
                   "{\"point\":1,\"step\":2,\"rows\":1,\"bytes\":20,\"last_time_s\":1}\n");
  const auto journal = RunRecorder::read_journal(dir / "points.jsonl");
  ASSERT_EQ(journal.size(), 2u);
  EXPECT_EQ(journal.back().point, 1);
  // A point that matches neither numbering is a broken journal, named by line.
  test::write_file(dir / "points.jsonl", "{\"point\":5,\"step\":1,\"rows\":1,\"bytes\":10,\"last_time_s\":0}\n"
                                         "{\"point\":2,\"step\":2,\"rows\":1,\"bytes\":20,\"last_time_s\":1}\n");
  EXPECT_THROW(RunRecorder::read_journal(dir / "points.jsonl"), InputError);
}

// Appends points 0..n-1 of `rows` rows each, first attempt of session 1; returns the size of
// samples.csv after them (all durable).
uint64_t append_points(RunRecorder& rec, int64_t n, int rows) {
  for (int64_t p = 0; p < n; ++p) rec.append_point(p, point_rows(p, rows, static_cast<double>(p)), 1, 1);
  return fs::file_size(rec.dir() / "samples.csv");
}
uint64_t append_points(RunRecorder&& rec, int64_t n, int rows) { return append_points(rec, n, rows); }

TEST(Recorder, ResumeCutsATornPointAndATornJournalLine) {
  TempDir tmp("recorder-torn");
  const fs::path dir = tmp / "run";
  const uint64_t synced = append_points(RunRecorder(dir), 3, 5);
  // A crash in the middle of point 3: two of its rows reached the disk, its journal line half.
  {
    std::ofstream s(dir / "samples.csv", std::ios::app);
    s << "3.0,offset,4,30,-15,103,-200,103,30,7,0,0,0,0,0,0,0,20.5,1,1\n3.02,offs";
    std::ofstream j(dir / "points.jsonl", std::ios::app);
    j << "{\"point\":3,\"step\":4,\"ro";
  }
  RunRecorder rec(dir);
  EXPECT_EQ(rec.next_point(), 3);
  EXPECT_EQ(fs::file_size(dir / "samples.csv"), synced);
  EXPECT_GT(rec.cut_bytes(), 0u);
  EXPECT_DOUBLE_EQ(rec.last_time_s(), 2.08);
  // The point is measured again, once.
  rec.append_point(3, point_rows(3, 5, 3.0), 2, 2);
  const SampleTable t = read_samples_csv(dir / "samples.csv");
  ASSERT_EQ(t.size(), 20u);
  int rows_of_4 = 0;
  for (size_t i = 0; i < t.size(); ++i) rows_of_4 += t.step[i] == 4;
  EXPECT_EQ(rows_of_4, 5);
  const auto journal = RunRecorder::read_journal(dir / "points.jsonl");
  ASSERT_EQ(journal.size(), 4u);
  EXPECT_EQ(journal.back().session, 2);
  EXPECT_EQ(journal.back().attempts, 2);
}

TEST(Recorder, AnUnreadableLastJournalLineIsAPointNotYetDone) {
  TempDir tmp("recorder-nul");
  const fs::path dir = tmp / "run";
  uint64_t synced = 0;
  {
    RunRecorder rec(dir);
    synced = append_points(rec, 2, 2);
    rec.append_point(2, point_rows(2, 2, 2), 1, 1);
  }
  // A power cut can leave the unsynced journal's last line as zeros.
  const std::string j = test::read_file(dir / "points.jsonl");
  const size_t last = j.rfind('\n', j.size() - 2) + 1;
  test::write_file(dir / "points.jsonl", j.substr(0, last) + std::string(j.size() - last - 1, '\0') + "\n");
  RunRecorder rec(dir);
  EXPECT_EQ(rec.next_point(), 2);
  EXPECT_EQ(fs::file_size(dir / "samples.csv"), synced);
  rec.append_point(2, point_rows(2, 2, 2), 1, 2);
  EXPECT_EQ(RunRecorder::read_journal(dir / "points.jsonl").size(), 3u);
}

TEST(Recorder, ResumeOfAFolderWithHeaderOnly) {
  TempDir tmp("recorder-empty");
  const fs::path dir = tmp / "run";
  { RunRecorder rec(dir); }
  { std::ofstream s(dir / "samples.csv", std::ios::app); s << "0,null,1,0,0,1,2"; }  // torn first row
  RunRecorder rec(dir);
  EXPECT_EQ(rec.next_point(), 0);
  EXPECT_FALSE(rec.has_rows());
  EXPECT_EQ(read_samples_csv(dir / "samples.csv").size(), 0u);
}

TEST(Recorder, DamagedRecordingsAreRefused) {
  TempDir tmp("recorder-bad");
  const fs::path dir = tmp / "run";
  {
    RunRecorder rec(dir);
    for (int64_t p = 0; p < 2; ++p) rec.append_point(p, point_rows(p, 2, p), 1, 1);
  }
  // samples.csv shorter than the journal says was synced: data was lost outside the stand.
  fs::resize_file(dir / "samples.csv", 50);
  EXPECT_THROW(RunRecorder{dir}, InputError);
  // A journal with a gap.
  const fs::path dir2 = tmp / "run2";
  fs::create_directories(dir2);
  test::write_file(dir2 / "points.jsonl",
                   "{\"point\":0,\"step\":1,\"rows\":1,\"bytes\":10,\"last_time_s\":0}\n"
                   "{\"point\":2,\"step\":3,\"rows\":1,\"bytes\":20,\"last_time_s\":1}\n");
  try {
    RunRecorder::read_journal(dir2 / "points.jsonl");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("points.jsonl:2: point 3 follows point 1"), std::string::npos) << e.what();
  }
}

TEST(Recorder, RunFoldersAreUniqueAndNamed) {
  TempDir tmp("recorder-dirs");
  const auto a = make_run_dir(tmp.path(), "2026-01-02T03:04:05Z", "FPSS1-SN/42", "discrete_grid");
  const auto b = make_run_dir(tmp.path(), "2026-01-02T03:04:05Z", "FPSS1-SN/42", "discrete_grid");
  EXPECT_EQ(a.filename(), "20260102T030405Z-FPSS1-SN_42-discrete_grid");
  EXPECT_EQ(b.filename(), "20260102T030405Z-FPSS1-SN_42-discrete_grid-2");
  EXPECT_TRUE(fs::is_directory(a));
  EXPECT_TRUE(fs::is_directory(b));
}

TEST(Recorder, JsonIsReplacedAtomically) {
  TempDir tmp("recorder-json");
  const auto f = tmp / "run.json";
  write_json_atomic(f, {{"outcome", "running"}});
  write_json_atomic(f, {{"outcome", "completed"}});
  EXPECT_EQ(read_json_file(f)["outcome"], "completed");
  EXPECT_FALSE(fs::exists(tmp / "run.json.tmp"));
  test::write_file(tmp / "bad.json", "{\"a\": ");
  EXPECT_THROW(read_json_file(tmp / "bad.json"), InputError);
}

// --- clock alignment ---

TEST(Align, HermiteIsExactForConstantAcceleration) {
  // p(t) = 3 + 20 t + 0.5 * 3600 t^2, sampled sparsely (a gap of 0.2 s).
  auto p = [](double t) { return 3 + 20 * t + 1800 * t * t; };
  auto v = [](double t) { return 20 + 3600 * t; };
  std::vector<GimbalFix> fixes;
  for (double t : {0.0, 0.2, 0.25}) fixes.push_back({t, t, p(t), -p(t), v(t), -v(t), 3});
  for (double t : {0.0, 0.05, 0.1337, 0.2, 0.23}) {
    auto at = interpolate_at(fixes, t);
    ASSERT_TRUE(at);
    EXPECT_NEAR(at->pitch_arcsec, p(t), 1e-9) << t;
    EXPECT_NEAR(at->yaw_arcsec, -p(t), 1e-9) << t;
  }
  EXPECT_NEAR(interpolate_at(fixes, 0.1)->gap_s, 0.2, 1e-12);
  EXPECT_NEAR(interpolate_at(fixes, 0.22)->gap_s, 0.05, 1e-12);
  EXPECT_FALSE(interpolate_at(fixes, -0.001));  // never extrapolates
  EXPECT_FALSE(interpolate_at(fixes, 0.2501));
}

TEST(Align, ClockOffsetFromTheLatencyFloor) {
  // A device clock 5 s behind the host's, latencies 1..4 ms: the floor is the least latency.
  std::vector<double> host, dev;
  const double lat[] = {0.004, 0.001, 0.003, 0.002};
  for (int i = 0; i < 4; ++i) {
    dev.push_back(10.0 + i);
    host.push_back(15.0 + i + lat[i]);
  }
  EXPECT_NEAR(clock_offset(host, dev, 1.0), 5.001, 1e-12);
  // With a bench running 20x faster than the host.
  std::vector<double> host20;
  for (int i = 0; i < 4; ++i) host20.push_back((10.0 + i) / 20 + 1 + lat[i]);
  EXPECT_NEAR(clock_offset(host20, dev, 20.0), 20.02, 1e-9);
}

TEST(Align, UnwrapNear) {
  const double wrap = 4294.967296;
  EXPECT_NEAR(unwrap_near(1000000u, 1.0), 1.0, 1e-12);
  // 2.5 wraps later, the counter shows 0.5 wrap + 1 s.
  const double t = 2 * wrap + 1.0;
  EXPECT_NEAR(unwrap_near(1000000u, t + 0.3), t, 1e-9);
  // Just before a wrap while the reference is just after it.
  EXPECT_NEAR(unwrap_near(4294967000u, wrap + 0.001), 4294.967, 1e-9);
}

}  // namespace
}  // namespace fpss
