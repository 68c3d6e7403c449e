// The run catalogue on a real SQLite file: schema, records, bad files, concurrent writers, killed writers.
#include "stand/catalogue/sqlite_catalogue.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <SQLiteCpp/SQLiteCpp.h>
#include <fmt/format.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <set>

#include "base/errors.h"
#include "calib/coefficients.h"
#include "tests/stand/catalogue_fixtures.h"
#include "tests/support/test_support.h"
#include "tests/support/text_order.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using test::fork_child;
using test::make_run;

using test::TempDir;

nlohmann::json calibration_json(const std::string& unit, double pitch_mean) {
  auto j = to_json(load_published("a-6-fpss1"));
  j["unit"] = unit;
  j["method"] = "differences";
  j["residuals"] = {
      {"pitch", {{"mean_abs_arcsec", pitch_mean}, {"sd_arcsec", 0.2}, {"max_abs_arcsec", 0.9},
                 {"points", 40}, {"range_deg", {-0.42, 0.42}}}},
      {"yaw", {{"mean_abs_arcsec", 0.31}, {"sd_arcsec", 0.25}, {"max_abs_arcsec", 1.1},
               {"points", 38}, {"range_deg", {-0.41, 0.41}}}}};
  return j;
}

int64_t count_rows(const fs::path& db, const std::string& table, const std::string& where = "1") {
  SQLite::Database d(db, SQLite::OPEN_READONLY);
  return d.execAndGet(fmt::format("SELECT count(*) FROM {} WHERE {}", table, where)).getInt64();
}

void write_all(int fd, const std::string& s) {
  size_t off = 0;
  while (off < s.size()) {
    const ssize_t n = ::write(fd, s.data() + off, s.size() - off);
    if (n <= 0) throw std::runtime_error("pipe write failed");
    off += static_cast<size_t>(n);
  }
}

// Reads one line from the pipe (blocking); empty on end of file.
std::string read_line(int fd) {
  std::string line;
  char c;
  while (::read(fd, &c, 1) == 1) {
    if (c == '\n') return line;
    line += c;
  }
  return line;
}

TEST(Catalogue, CreatesTheSchemaOnceAndReopens) {
  TempDir dir;
  const auto db = dir.path() / "sub" / "stand.db";
  {
    SqliteCatalogue c(db);
    EXPECT_EQ(c.schema_version(), Catalogue::kSchemaVersion);
    EXPECT_EQ(c.database().execAndGet("PRAGMA journal_mode").getString(), "wal");
    EXPECT_TRUE(c.add_unit("FPSS1"));
    EXPECT_FALSE(c.add_unit("FPSS1"));
  }
  SqliteCatalogue again(db);
  EXPECT_EQ(again.units(), std::vector<std::string>{"FPSS1"});
  SqliteCatalogue ro(db, Catalogue::Mode::read_only);
  EXPECT_TRUE(ro.has_unit("FPSS1"));
  EXPECT_FALSE(ro.has_unit("FPSS9"));
  EXPECT_EQ(ro.integrity_check(), "ok");
  EXPECT_EQ(Catalogue::default_path("somewhere"), fs::path("somewhere") / "stand.db");
}

TEST(Catalogue, RecordsRunsFromStartToEndAndCountsResumes) {
  TempDir dir;
  SqliteCatalogue c(dir.path() / "stand.db");
  c.record_run_start(make_run("20240501T120000Z-FPSS1-discrete_grid", "FPSS1", "2024-05-01T12:00:00Z"));
  c.record_run_start(make_run("20240502T080000Z-FPSS2-full_grid", "FPSS2", "2024-05-02T08:00:00Z"));

  auto runs = c.list_runs();
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0].run_id, "20240502T080000Z-FPSS2-full_grid");  // most recent first
  EXPECT_TRUE(runs[1].running());
  EXPECT_FALSE(runs[1].ended_utc);
  EXPECT_FALSE(runs[1].stale());  // this process is alive
  EXPECT_TRUE(fs::path(runs[1].run_dir).is_absolute());
  EXPECT_EQ(runs[1].software_version, FPSS_VERSION);
  EXPECT_TRUE(runs[1].emulated);

  c.record_run_end("20240501T120000Z-FPSS1-discrete_grid", RunOutcome::interrupted, "2024-05-01T12:05:00Z");
  auto r = c.find_run("20240501T120000Z-FPSS1-discrete_grid");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->outcome, RunOutcome::interrupted);
  EXPECT_EQ(r->ended_utc.value_or(""), "2024-05-01T12:05:00Z");

  // Resume: same id, later start time given; the original start stays, the end is cleared.
  c.record_run_start(make_run("20240501T120000Z-FPSS1-discrete_grid", "FPSS1", "2024-05-01T13:00:00Z"));
  r = c.find_run("20240501T120000Z-FPSS1-discrete_grid");
  EXPECT_EQ(r->started_utc, "2024-05-01T12:00:00Z");
  EXPECT_TRUE(r->running());
  EXPECT_FALSE(r->ended_utc);
  EXPECT_EQ(r->resumes, 1);
  c.record_run_end("20240501T120000Z-FPSS1-discrete_grid", RunOutcome::completed);
  EXPECT_EQ(c.find_run("20240501T120000Z-FPSS1-discrete_grid")->outcome, RunOutcome::completed);

  EXPECT_EQ(c.list_runs({.unit = "FPSS2"}).size(), 1u);
  EXPECT_EQ(c.list_runs({.unit = std::nullopt, .limit = 1}).size(), 1u);
  EXPECT_FALSE(c.find_run("nope"));
  EXPECT_EQ(c.units(), (std::vector<std::string>{"FPSS1", "FPSS2"}));

  // A resume under another unit is a bug, an unknown run cannot end, a run needs a unit.
  EXPECT_THROW(c.record_run_start(make_run("20240501T120000Z-FPSS1-discrete_grid", "FPSS2")),
               std::invalid_argument);
  EXPECT_THROW(c.record_run_end("nope", RunOutcome::completed), std::invalid_argument);
  EXPECT_THROW(c.record_run_start(make_run("x", "")), InputError);
}

// A run's outcome is a RunOutcome, "running" its absence; any other text in a file or a row is
// bad input naming where it was read.
TEST(CatalogueOutcome, ItsTextIsReadAsATypeOrRefused) {
  EXPECT_EQ(RunRecord::outcome_of("running", "x"), std::nullopt);
  EXPECT_EQ(RunRecord::outcome_of("interrupted", "x"), RunOutcome::interrupted);
  RunRecord r;
  EXPECT_EQ(r.outcome_name(), "running");
  r.outcome = RunOutcome::failed;
  EXPECT_EQ(r.outcome_name(), "failed");
  try {
    RunRecord::outcome_of("done", "runs/a/run.json: outcome");
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("runs/a/run.json: outcome"), std::string::npos);
  }
}

TEST(Catalogue, KeepsEachUnitsCalibrationsInDateOrder) {
  TempDir dir;
  SqliteCatalogue c(dir.path() / "stand.db");
  c.record_run_start(make_run("r1", "FPSS1", "2024-05-03T10:00:00Z"));

  auto from_run = CalibrationRecord::from_calibration_json(calibration_json("FPSS1", 0.42), "calibration.json");
  from_run.run_id = "r1";
  from_run.date_utc = "2024-05-03T10:30:00Z";
  EXPECT_EQ(from_run.method, "differences");
  ASSERT_TRUE(from_run.pitch);
  const int64_t id_run = c.record_calibration(from_run);

  // Imports of the paper's calibrations, entered out of order.
  for (const auto& [name, label] : {std::pair{"a-7-fpss1", "VI"}, std::pair{"a-2-fpss1", "I"}}) {
    const auto set = load_published(name);
    CalibrationRecord imp;
    imp.unit = "FPSS1";
    imp.source = "import";
    imp.source_ref = published_dir() / (std::string(name) + ".json");
    imp.label = label;
    imp.date_utc = set.extra.value("date", "");
    imp.method = "imported";
    imp.coefficients = to_json(set);
    if (label == std::string("I")) {
      imp.pitch = AxisResidualStats::from_json(
          {{"mean_abs_arcsec", nullptr}, {"max_abs_arcsec", 0.9}, {"points", 25}}, "table 1");
    }
    c.record_calibration(imp);
  }

  const auto hist = c.unit_history("FPSS1");
  ASSERT_EQ(hist.size(), 3u);
  EXPECT_LT(hist[0].date_utc, hist[1].date_utc);
  EXPECT_EQ(hist[1].label, "VI");
  EXPECT_EQ(hist[1].date_utc, "1980-09-04");
  EXPECT_FALSE(hist[1].pitch);  // imports without a residuals block have no statistics
  // An import with Table 1's partial figures (calibration II prints only max and points).
  ASSERT_TRUE(hist[0].pitch);
  EXPECT_FALSE(hist[0].pitch->mean_abs_arcsec);
  EXPECT_DOUBLE_EQ(hist[0].pitch->max_abs_arcsec.value(), 0.9);
  EXPECT_EQ(hist[0].pitch->points.value(), 25);
  EXPECT_FALSE(hist[0].yaw);
  EXPECT_EQ(hist[2].id, id_run);
  EXPECT_EQ(hist[2].source, "run");
  EXPECT_EQ(hist[2].source_ref, "r1");
  ASSERT_TRUE(hist[2].pitch && hist[2].yaw);
  EXPECT_DOUBLE_EQ(hist[2].pitch->mean_abs_arcsec.value(), 0.42);
  EXPECT_EQ(hist[2].yaw->points.value(), 38);
  EXPECT_DOUBLE_EQ(hist[2].yaw->range_lo_deg.value(), -0.41);
  EXPECT_DOUBLE_EQ(hist[2].yaw->range_hi_deg.value(), 0.41);
  EXPECT_FALSE(hist[2].yaw->rms_arcsec);
  EXPECT_EQ(hist[2].yaw->to_json(), calibration_json("FPSS1", 0.42)["residuals"]["yaw"]);
  // The stored coefficients read back as the same coefficient set.
  const auto back = parse_coefficients(hist[2].coefficients, "catalogue");
  EXPECT_EQ(back.alpha, load_published("a-6-fpss1").alpha);

  EXPECT_EQ(c.run_calibrations("r1").size(), 1u);
  EXPECT_EQ(c.find_calibration(id_run)->unit, "FPSS1");
  EXPECT_FALSE(c.find_calibration(99999));
  EXPECT_TRUE(c.unit_history("FPSS2").empty());

  CalibrationRecord orphan = from_run;
  orphan.run_id = "no-such-run";
  EXPECT_THROW(c.record_calibration(orphan), std::invalid_argument);
  orphan.source = "import";  // an import cannot name a run
  EXPECT_THROW(c.record_calibration(orphan), std::invalid_argument);
}

TEST(Catalogue, CalibrationJsonWithBadResidualsIsAnInputError) {
  auto j = calibration_json("FPSS1", 0.4);
  j["residuals"]["yaw"]["points"] = "many";
  try {
    CalibrationRecord::from_calibration_json(j, "run/calibration.json");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("run/calibration.json: residuals.yaw"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("points"), std::string::npos) << e.what();
  }
  j = calibration_json("FPSS1", 0.4);
  j["residuals"]["pitch"]["range_deg"] = 0.84;  // the calibrator writes [lo, hi]
  EXPECT_THROW(CalibrationRecord::from_calibration_json(j, "x.json"), InputError);
  j = calibration_json("FPSS1", 0.4);
  j["alpha"].erase(0);
  EXPECT_THROW(CalibrationRecord::from_calibration_json(j, "x.json"), InputError);
}

TEST(Catalogue, StoresAcceptancesWithTheirCertificates) {
  TempDir dir;
  SqliteCatalogue c(dir.path() / "stand.db");
  c.record_run_start(make_run("acc1", "SN-0042"));
  AcceptanceRecord a;
  a.unit = "SN-0042";
  a.run_id = "acc1";
  a.passed = false;
  a.certificate = {{"verdict", "fail"}, {"criteria", {{{"name", "jitter_3sigma_arcsec"}, {"value", 3.4}}}}};
  const int64_t id = c.record_acceptance(a);
  a.run_id.reset();
  a.passed = true;
  c.record_acceptance(a);
  const auto acc = c.unit_acceptances("SN-0042");
  ASSERT_EQ(acc.size(), 2u);
  EXPECT_EQ(acc[0].id, id);
  EXPECT_FALSE(acc[0].passed);
  EXPECT_EQ(acc[0].run_id.value_or(""), "acc1");
  EXPECT_DOUBLE_EQ(acc[0].certificate["criteria"][0]["value"].get<double>(), 3.4);
  EXPECT_TRUE(acc[1].passed);
  EXPECT_FALSE(acc[1].run_id);
}

TEST(Catalogue, BadFilesGiveClearErrors) {
  TempDir dir;
  const auto missing = dir.path() / "none.db";
  try {
    SqliteCatalogue c(missing, Catalogue::Mode::read_only);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(missing.string()), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(missing));  // reading never creates

  const auto text = dir.path() / "notes.db";
  std::ofstream(text) << "this is not a database, just some notes that are long enough to look like a header\n";
  for (auto mode : {Catalogue::Mode::read_only, Catalogue::Mode::read_write}) {
    try {
      SqliteCatalogue c(text, mode);
      FAIL() << "no error";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(text.string()), std::string::npos) << e.what();
    }
  }

  const auto empty_db = dir.path() / "empty.db";
  { SQLite::Database d(empty_db, SQLite::OPEN_READWRITE | SQLite::OPEN_CREATE); d.exec("CREATE TABLE t(x)"); }
  EXPECT_THROW(SqliteCatalogue(empty_db, Catalogue::Mode::read_only), InputError);

  const auto future = dir.path() / "future.db";
  { SqliteCatalogue c(future); c.database().exec("PRAGMA user_version = 99"); }
  for (auto mode : {Catalogue::Mode::read_only, Catalogue::Mode::read_write}) {
    try {
      SqliteCatalogue c(future, mode);
      FAIL() << "no error";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("99"), std::string::npos) << e.what();
    }
  }
}

// Several processes open a fresh file at the same moment (racing to create the schema) and
// each writes many runs and calibrations in its own short transactions.
TEST(Catalogue, ConcurrentWritersLoseNothing) {
  TempDir dir;
  const auto db = dir.path() / "stand.db";
  constexpr int kWriters = 4;
  constexpr int kRunsEach = 100;

  const auto done = test::fork_together(kWriters, [&](int w) {
    SqliteCatalogue cat(db);
    test::write_runs(cat, w, kRunsEach, 5, 1234, [](const std::string& id, const std::string& unit) {
      return make_run(id, unit);
    }, calibration_json);
  });
  for (int code : done.exit_codes) EXPECT_EQ(code, 0);
  std::printf("%d writers x %d runs (3 transactions each): %.2f s, %.0f commits/s\n", kWriters, kRunsEach,
              done.seconds, kWriters * kRunsEach * 3 / done.seconds);

  SqliteCatalogue cat(db, Catalogue::Mode::read_only);
  EXPECT_EQ(cat.integrity_check(), "ok");
  EXPECT_EQ(cat.schema_version(), Catalogue::kSchemaVersion);
  EXPECT_EQ(count_rows(db, "runs"), kWriters * kRunsEach);
  EXPECT_EQ(count_rows(db, "runs", "outcome = 'completed' AND ended_utc IS NOT NULL"), kWriters * kRunsEach);
  EXPECT_EQ(count_rows(db, "calibrations"), kWriters * kRunsEach);
  std::set<std::string> ids;
  for (const auto& r : cat.list_runs()) ids.insert(r.run_id);
  for (int w = 0; w < kWriters; ++w) {
    for (int i = 0; i < kRunsEach; ++i) EXPECT_TRUE(ids.count(test::writer_run_id(w, i)));
  }
  // Each calibration carries its own writer's residuals: no row was mixed with another.
  size_t cals = 0;
  for (const auto& u : cat.units()) {
    for (const auto& c : cat.unit_history(u)) {
      int w = -1, i = -1;
      ASSERT_TRUE(test::writer_of_run(c.run_id.value(), w, i));
      EXPECT_NEAR(c.pitch->mean_abs_arcsec.value(), test::writer_pitch_mean(w, i), 1e-12);
      EXPECT_EQ(c.unit, cat.find_run(*c.run_id)->unit);
      ++cals;
    }
  }
  EXPECT_EQ(cals, static_cast<size_t>(kWriters * kRunsEach));
}

// Several processes importing the same published calibrations at once: each is recorded once.
TEST(Catalogue, ConcurrentImportsOfOneFileRecordItOnce) {
  TempDir dir;
  const auto db = dir.path() / "stand.db";
  const std::vector<std::string> names = {"a-2-fpss1", "a-3-fpss1", "a-4-fpss1"};
  auto import_of = [](const std::string& name) {
    const auto set = load_published(name);
    CalibrationRecord c = CalibrationRecord::from_calibration_json(to_json(set), name);
    c.source = "import";
    c.source_ref = name + ".json";
    c.method = "imported";
    c.date_utc = set.extra.at("date").get<std::string>();
    return c;
  };
  constexpr int kImporters = 4;
  int done[2];
  ASSERT_EQ(::pipe(done), 0);
  const auto ended = test::fork_together(kImporters, [&](int) {
    ::close(done[0]);
    SqliteCatalogue cat(db);
    int inserted = 0;
    for (int round = 0; round < 10; ++round) {
      for (const auto& n : names) inserted += cat.record_import_once(import_of(n)).second ? 1 : 0;
    }
    write_all(done[1], fmt::format("{}\n", inserted));
  });
  ::close(done[1]);
  for (int code : ended.exit_codes) EXPECT_EQ(code, 0);
  int inserted = 0;
  for (int i = 0; i < kImporters; ++i) inserted += std::stoi(read_line(done[0]));
  ::close(done[0]);
  EXPECT_EQ(inserted, 3);
  EXPECT_EQ(count_rows(db, "calibrations"), 3);
  SqliteCatalogue cat(db);
  EXPECT_EQ(cat.integrity_check(), "ok");
  const auto again = cat.record_import_once(import_of("a-3-fpss1"));
  EXPECT_FALSE(again.second);
  EXPECT_EQ(cat.find_calibration(again.first)->label, "");
  auto other_date = import_of("a-3-fpss1");
  other_date.date_utc = "1981-01-01";
  EXPECT_TRUE(cat.record_import_once(other_date).second);
  auto from_run = import_of("a-3-fpss1");
  from_run.source = "run";
  EXPECT_THROW(cat.record_import_once(from_run), std::invalid_argument);
}

// A writer killed in the middle of a transaction: the file opens, is sound, keeps every committed
// row and none of the uncommitted ones, and another writer can go on at once.
TEST(Catalogue, WriterKilledMidTransactionLeavesASoundFile) {
  TempDir dir;
  const auto db = dir.path() / "stand.db";
  constexpr int kCommitted = 25;
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t kid = fork_child([&] {
    ::close(ready[0]);
    SqliteCatalogue cat(db);
    for (int i = 0; i < kCommitted; ++i) {
      const std::string id = fmt::format("committed-{:03}", i);
      cat.record_run_start(make_run(id, "FPSS1"));
      auto cal = CalibrationRecord::from_calibration_json(calibration_json("FPSS1", 0.5), id);
      cal.run_id = id;
      cat.record_calibration(cal);
    }
    // Open a transaction holding the write lock with many rows written, then wait to be killed.
    auto& d = cat.database();
    SQLite::Transaction txn(d, SQLite::TransactionBehavior::IMMEDIATE);
    SQLite::Statement st(d, "INSERT INTO runs(run_id, unit, procedure, procedure_hash, started_utc, outcome, "
                            "run_dir, emulated, software_version) VALUES(?, 'FPSS1', 'p', 'h', 't', 'running', "
                            "'d', 0, 'v')");
    for (int i = 0; i < 5000; ++i) {
      st.bind(1, fmt::format("uncommitted-{:05}", i));
      st.exec();
      st.reset();
    }
    d.exec("UPDATE calibrations SET method = 'torn' WHERE id % 2 = 0");
    write_all(ready[1], "in-transaction\n");
    for (;;) ::pause();
  });
  ::close(ready[1]);
  ASSERT_EQ(read_line(ready[0]), "in-transaction");
  ASSERT_EQ(::kill(kid, SIGKILL), 0);
  EXPECT_EQ(test::wait_exit_code(kid), 128 + SIGKILL);
  ::close(ready[0]);

  SqliteCatalogue cat(db);  // a writer again, straight away: the dead process's lock is gone
  EXPECT_EQ(cat.integrity_check(), "ok");
  EXPECT_EQ(count_rows(db, "runs"), kCommitted);
  EXPECT_EQ(count_rows(db, "runs", "run_id LIKE 'uncommitted-%'"), 0);
  EXPECT_EQ(count_rows(db, "calibrations", "method = 'differences'"), kCommitted);
  // The killed process's runs say `running` and are known to be stale.
  const auto runs = cat.list_runs();
  ASSERT_EQ(runs.size(), static_cast<size_t>(kCommitted));
  for (const auto& r : runs) EXPECT_TRUE(r.stale()) << r.run_id;
  cat.record_run_end("committed-000", RunOutcome::interrupted);
  cat.record_run_start(make_run("after-the-kill", "FPSS1"));
  EXPECT_EQ(count_rows(db, "runs"), kCommitted + 1);
}

// A writer killed at an arbitrary moment of a stream of commits (wherever the signal lands):
// every commit it reported is there, whole.
TEST(Catalogue, WriterKilledWhileWritingKeepsEveryReportedCommit) {
  TempDir dir;
  const auto db = dir.path() / "stand.db";
  int pipe_fd[2];
  ASSERT_EQ(::pipe(pipe_fd), 0);
  const pid_t kid = fork_child([&] {
    ::close(pipe_fd[0]);
    SqliteCatalogue cat(db);
    for (int i = 0;; ++i) {
      const std::string id = fmt::format("run-{:06}", i);
      cat.record_run_start(make_run(id, "FPSS2"));
      auto cal = CalibrationRecord::from_calibration_json(calibration_json("FPSS2", 0.001 * i), id);
      cal.run_id = id;
      cat.record_calibration(cal);
      write_all(pipe_fd[1], fmt::format("{}\n", i));
    }
  });
  ::close(pipe_fd[1]);
  int last = -1;
  while (last < 60) last = std::stoi(read_line(pipe_fd[0]));
  ASSERT_EQ(::kill(kid, SIGKILL), 0);
  EXPECT_EQ(test::wait_exit_code(kid), 128 + SIGKILL);
  ::close(pipe_fd[0]);

  SqliteCatalogue cat(db, Catalogue::Mode::read_only);
  EXPECT_EQ(cat.integrity_check(), "ok");
  const auto hist = cat.unit_history("FPSS2");
  ASSERT_GE(hist.size(), static_cast<size_t>(last + 1));
  for (int i = 0; i <= last; ++i) {
    const auto& c = hist[static_cast<size_t>(i)];
    EXPECT_EQ(c.run_id.value_or(""), fmt::format("run-{:06}", i));
    ASSERT_TRUE(c.yaw);
    EXPECT_NEAR(c.pitch->mean_abs_arcsec.value(), 0.001 * i, 1e-12);
  }
  // At most one run can lack its calibration: the one whose second transaction was cut.
  EXPECT_LE(count_rows(db, "runs") - static_cast<int64_t>(hist.size()), 1);
}

// ---- the command line: fpss-stand runs / history over a real catalogue ----

class CatalogueCli : public ::testing::Test {
 protected:
  void SetUp() override {
    runs_dir_ = dir_.path() / "runs";
    SqliteCatalogue c(Catalogue::default_path(runs_dir_));
    c.record_run_start(make_run("20240501T120000Z-FPSS1-discrete_grid", "FPSS1", "2024-05-01T12:00:00Z"));
    auto cal = CalibrationRecord::from_calibration_json(calibration_json("FPSS1", 0.26), "calibration.json");
    cal.run_id = "20240501T120000Z-FPSS1-discrete_grid";
    cal.date_utc = "2024-05-01T12:20:00Z";
    c.record_calibration(cal);
    c.record_run_end("20240501T120000Z-FPSS1-discrete_grid", RunOutcome::completed, "2024-05-01T12:21:00Z");
    c.record_run_start(make_run("20240502T090000Z-SN-7-full_grid", "SN-7", "2024-05-02T09:00:00Z"));
    c.record_run_end("20240502T090000Z-SN-7-full_grid", RunOutcome::failed, "2024-05-02T09:03:00Z");
    CalibrationRecord imp;
    imp.unit = "FPSS1";
    imp.source = "import";
    imp.source_ref = "a-7-fpss1.json";
    imp.label = "VI";
    imp.date_utc = "1980-09-04";
    imp.method = "imported";
    imp.coefficients = to_json(load_published("a-7-fpss1"));
    c.record_calibration(imp);
  }
  TempDir dir_;
  fs::path runs_dir_;
};

TEST_F(CatalogueCli, RunsListsEveryRunMostRecentFirst) {
  const auto r = test::run_stand_shell(fmt::format("runs --runs-dir '{}'", runs_dir_.string()), dir_.path());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(
      test::appear_in_order(r.out, {"20240502T090000Z-SN-7-full_grid", "20240501T120000Z-FPSS1-discrete_grid"}));
  EXPECT_NE(r.out.find("failed"), std::string::npos);
  EXPECT_NE(r.out.find("completed"), std::string::npos);
  EXPECT_NE(r.out.find("OUTCOME"), std::string::npos);

  const auto j = test::run_stand_shell(fmt::format("runs --db '{}' --json --unit FPSS1",
                                                   Catalogue::default_path(runs_dir_).string()), dir_.path());
  ASSERT_EQ(j.code, 0) << j.err;
  const auto arr = nlohmann::json::parse(j.out);
  ASSERT_EQ(arr.size(), 1u);
  EXPECT_EQ(arr[0]["run_id"], "20240501T120000Z-FPSS1-discrete_grid");
  EXPECT_EQ(arr[0]["ended_utc"], "2024-05-01T12:21:00Z");
  EXPECT_EQ(arr[0]["emulated"], true);
}

TEST_F(CatalogueCli, HistoryListsTheUnitsCalibrationsOldestFirst) {
  const auto r = test::run_stand_shell(fmt::format("history FPSS1 --runs-dir '{}'", runs_dir_.string()), dir_.path());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(test::appear_in_order(r.out, {"import a-7-fpss1.json", "run 20240501T120000Z-FPSS1-discrete_grid"}));
  EXPECT_NE(r.out.find("0.26 +- 0.20"), std::string::npos) << r.out;  // pitch mean +- sd
  EXPECT_NE(r.out.find("-0.41..+0.41"), std::string::npos) << r.out;  // yaw range

  const auto j = test::run_stand_shell(fmt::format("history FPSS1 --db '{}' --json",
                                                   Catalogue::default_path(runs_dir_).string()), dir_.path());
  ASSERT_EQ(j.code, 0) << j.err;
  const auto h = nlohmann::json::parse(j.out);
  EXPECT_EQ(h["unit"], "FPSS1");
  ASSERT_EQ(h["calibrations"].size(), 2u);
  EXPECT_EQ(h["calibrations"][0]["label"], "VI");
  EXPECT_TRUE(h["calibrations"][0]["residuals"]["pitch"].is_null());
  EXPECT_DOUBLE_EQ(h["calibrations"][1]["residuals"]["pitch"]["mean_abs_arcsec"].get<double>(), 0.26);
  EXPECT_EQ(h["calibrations"][1]["residuals"]["yaw"]["points"], 38);
  // The coefficients come back whole: they read as the set that was stored.
  EXPECT_EQ(parse_coefficients(h["calibrations"][0]["coefficients"], "json").beta,
            load_published("a-7-fpss1").beta);
}

TEST_F(CatalogueCli, UnknownUnitOrMissingCatalogueIsExit2NamingWhat) {
  const auto db = Catalogue::default_path(runs_dir_).string();
  auto r = test::run_stand_shell(fmt::format("history FPSS9 --db '{}'", db), dir_.path());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("FPSS9"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(db), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("FPSS1, SN-7"), std::string::npos) << r.err;  // what is there instead
  EXPECT_TRUE(r.out.empty());

  // A unit with runs, no calibration.
  r = test::run_stand_shell(fmt::format("history SN-7 --db '{}'", db), dir_.path());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("SN-7"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("no calibration"), std::string::npos) << r.err;

  const auto none = (dir_.path() / "elsewhere").string();
  for (const auto& args : {fmt::format("runs --runs-dir '{}'", none), fmt::format("history FPSS1 --runs-dir '{}'", none)}) {
    r = test::run_stand_shell(args, dir_.path());
    EXPECT_EQ(r.code, 2) << args;
    EXPECT_NE(r.err.find(none), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(none));  // listing never creates a catalogue

  r = test::run_stand_shell(fmt::format("runs --runs-dir a --db '{}'", db), dir_.path());
  EXPECT_EQ(r.code, 2);
}

}  // namespace
}  // namespace fpss
