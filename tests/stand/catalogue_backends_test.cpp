// One suite, both backends: the catalogue's semantics on a real SQLite file and on a real PostgreSQL
// server started by the test (tests/support/pg_server.h): records, order, schema versions and
// migrations, concurrent writers (processes), imports recorded once, copy between backends.
#include <fcntl.h>
#include <sys/file.h>

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <SQLiteCpp/SQLiteCpp.h>
#include <fmt/format.h>

#include <atomic>
#include <functional>
#include <random>
#include <set>

#include "base/errors.h"
#include "base/unique_fd.h"
#include "calib/coefficients.h"
#include "calib/msa.h"
#include "stand/catalogue/copy.h"
#include "stand/catalogue/postgres_catalogue.h"
#include "stand/catalogue/schema.h"
#include "stand/catalogue/sqlite_catalogue.h"
#include "tests/stand/catalogue_fixtures.h"
#include "tests/support/pg_server.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using test::fork_child;

// One server for the whole binary; one database per test.
test::PgServer& pg() {
  static test::PgServer server;
  return server;
}

// Runs of these tests come from stand A.
RunStart make_run(const std::string& id, const std::string& unit, const std::string& started = "") {
  return test::make_run(id, unit, started, "stand-A");
}

nlohmann::json calibration_json(const std::string& unit, double pitch_mean) {
  auto j = to_json(load_published("a-6-fpss1"));
  j["unit"] = unit;
  j["method"] = "differences";
  j["residuals"] = {{"pitch", {{"mean_abs_arcsec", pitch_mean}, {"sd_arcsec", 0.2}, {"max_abs_arcsec", 0.9},
                               {"points", 40}, {"range_deg", {-0.42, 0.42}}}},
                    {"yaw", {{"mean_abs_arcsec", 0.31}, {"points", 38}}}};
  return j;
}

// An imported calibration of `unit` for an MSA study of the angle at zero counts: its C1 puts
// `c1_arcsec` there; `pitch_mean` is its residuals' mean (calibration_json).
CalibrationRecord msa_calibration(const std::string& unit, double c1_arcsec, double pitch_mean,
                                  const std::string& source_ref, const std::string& stand, const std::string& date) {
  auto j = calibration_json(unit, pitch_mean);
  j["alpha"][0] = c1_arcsec / 206264.80624709636;
  auto cal = CalibrationRecord::from_calibration_json(j, "msa");
  cal.unit = unit;
  cal.source = "import";
  cal.source_ref = source_ref;
  cal.stand = stand;
  cal.date_utc = date;
  return cal;
}

enum class Backend { sqlite, postgresql };

class Backends : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    static std::atomic<int> n{0};
    if (GetParam() == Backend::sqlite) {
      url_ = "sqlite:" + (dir_.path() / "stand.db").string();
    } else {
      db_ = fmt::format("t{}_{}", ::getpid(), n++);
      url_ = pg().create_database(db_);
    }
  }
  std::unique_ptr<Catalogue> open(Catalogue::Mode m = Catalogue::Mode::read_write) { return open_catalogue(url_, m); }
  // Writes a schema version into the catalogue behind its back (a newer binary, or an old file).
  void set_version(int v) {
    if (GetParam() == Backend::sqlite) {
      SQLite::Database d(dir_.path() / "stand.db", SQLite::OPEN_READWRITE);
      d.exec(fmt::format("PRAGMA user_version = {}", v));
    } else {
      pg().psql(db_, fmt::format("UPDATE schema_version SET version = {}", v));
    }
  }
  // A catalogue made by a binary that knew only schema version `v`, holding unit OLD-1 and what
  // `sql` adds (SQL both dialects read alike).
  void make_version(int v, const std::string& sql = "") {
    const auto dialect = GetParam() == Backend::sqlite ? schema::Dialect::sqlite : schema::Dialect::postgres;
    std::string all;
    for (int step = 0; step < v; ++step) all += schema::migration(step, dialect);
    all += "INSERT INTO units VALUES('OLD-1', '2024-01-01T00:00:00Z');" + sql;
    if (GetParam() == Backend::sqlite) {
      SQLite::Database d(dir_.path() / "stand.db", SQLite::OPEN_READWRITE | SQLite::OPEN_CREATE);
      d.exec(all);
      d.exec(fmt::format("PRAGMA user_version = {}", v));
    } else {
      pg().psql(db_, fmt::format("CREATE TABLE schema_version (version INTEGER NOT NULL);"
                                 "INSERT INTO schema_version VALUES ({});",
                                 v) +
                         all);
    }
  }
  void make_version_1() { make_version(1); }
  // Whether the catalogue's `table` has `column`, as the database itself lists them.
  bool has_column(const std::string& table, const std::string& column) {
    if (GetParam() == Backend::sqlite) {
      SQLite::Database d(dir_.path() / "stand.db", SQLite::OPEN_READONLY);
      SQLite::Statement q(d, "SELECT count(*) FROM pragma_table_info(?) WHERE name = ?");
      q.bind(1, table);
      q.bind(2, column);
      return q.executeStep() && q.getColumn(0).getInt() == 1;
    }
    return pg().psql(db_, fmt::format("SELECT count(*) FROM information_schema.columns WHERE table_name = '{}' "
                                      "AND column_name = '{}'",
                                      table, column))
               .rfind("1", 0) == 0;
  }

  test::TempDir dir_;
  std::string url_, db_;
};

TEST_P(Backends, RecordsRunsFromStartToEndAndCountsResumes) {
  auto c = open();
  EXPECT_EQ(c->schema_version(), Catalogue::kSchemaVersion);
  c->record_run_start(make_run("r1", "SN-1", "2024-05-01T10:00:00Z"));
  c->record_run_start(make_run("r2", "SN-1", "2024-05-02T10:00:00Z"));
  c->record_run_start(make_run("r3", "SN-2", "2024-05-03T10:00:00Z"));
  c->record_run_end("r1", RunOutcome::interrupted, "2024-05-01T11:00:00Z");
  c->record_run_start(make_run("r1", "SN-1", "2099-01-01T00:00:00Z"));  // a resume keeps the start
  c->record_run_end("r1", RunOutcome::completed);
  EXPECT_THROW(c->record_run_end("nope", RunOutcome::completed), std::invalid_argument);
  EXPECT_THROW(c->record_run_start(make_run("r1", "SN-9")), std::invalid_argument);  // another unit's id

  const auto runs = c->list_runs();
  ASSERT_EQ(runs.size(), 3u);
  EXPECT_EQ(runs[0].run_id, "r3");  // most recent first
  EXPECT_EQ(runs[2].run_id, "r1");
  const auto r1 = c->find_run("r1").value();
  EXPECT_EQ(r1.started_utc, "2024-05-01T10:00:00Z");
  EXPECT_EQ(r1.outcome, RunOutcome::completed);
  EXPECT_EQ(r1.resumes, 1);
  EXPECT_EQ(r1.stand, "stand-A");
  EXPECT_EQ(r1.host, this_host());
  EXPECT_EQ(r1.pid, ::getpid());
  EXPECT_TRUE(fs::path(r1.run_dir).is_absolute());
  EXPECT_EQ(c->list_runs({.unit = "SN-1", .limit = 1}).size(), 1u);
  EXPECT_EQ(c->list_runs({.unit = "SN-1", .limit = 1})[0].run_id, "r2");
  EXPECT_EQ(c->units(), (std::vector<std::string>{"SN-1", "SN-2"}));
  // A run of several units ("SN-7+SN_8") is each unit's run; a part of a serial is none.
  c->record_run_start(make_run("r4", "SN-7+SN_8", "2024-05-04T10:00:00Z"));
  EXPECT_EQ(c->list_runs({.unit = "SN_8"}).size(), 1u);
  EXPECT_EQ(c->list_runs({.unit = "SN-7"}).size(), 1u);
  EXPECT_TRUE(c->list_runs({.unit = "SN"}).empty());
  EXPECT_TRUE(c->list_runs({.unit = "SN-8"}).empty());  // '_' is no wildcard
  EXPECT_EQ(c->list_runs({.unit = "SN-2"}).size(), 1u);
  EXPECT_EQ(c->units(), (std::vector<std::string>{"SN-1", "SN-2", "SN-7", "SN_8"}));
  EXPECT_TRUE(c->has_unit("SN-2"));
  EXPECT_FALSE(c->has_unit("SN-3"));
  EXPECT_FALSE(c->add_unit("SN-2"));
  EXPECT_TRUE(c->add_unit("SN-3"));
  EXPECT_EQ(c->integrity_check(), "ok");
}

TEST_P(Backends, KeepsCalibrationsInDateOrderWithTheirStatsAndOrigin) {
  auto c = open();
  c->record_run_start(make_run("r1", "SN-1"));
  auto late = CalibrationRecord::from_calibration_json(calibration_json("SN-1", 0.26), "late");
  late.source = "run";
  late.run_id = "r1";
  late.date_utc = "2024-06-01T00:00:00Z";
  late.stand = "stand-A";
  const int64_t late_id = c->record_calibration(late);
  auto early = CalibrationRecord::from_calibration_json(calibration_json("SN-1", 0.5), "early");
  early.source = "import";
  early.source_ref = "/elsewhere/early.json";
  early.date_utc = "2024-01-01";
  early.label = "VI";
  const auto [early_id, fresh] = c->record_import_once(early);
  EXPECT_TRUE(fresh);
  EXPECT_EQ(c->record_import_once(early), std::make_pair(early_id, false));  // the same import again: no-op
  auto orphan = late;
  orphan.run_id = "no-such-run";
  EXPECT_THROW(c->record_calibration(orphan), std::invalid_argument);

  const auto h = c->unit_history("SN-1");
  ASSERT_EQ(h.size(), 2u);
  EXPECT_EQ(h[0].id, early_id);
  EXPECT_EQ(h[0].label, "VI");
  EXPECT_FALSE(h[0].run_id.has_value());
  EXPECT_EQ(h[1].id, late_id);
  EXPECT_EQ(h[1].run_id.value(), "r1");
  EXPECT_EQ(h[1].stand, "stand-A");
  EXPECT_EQ(h[1].host, this_host());
  EXPECT_DOUBLE_EQ(h[1].pitch->mean_abs_arcsec.value(), 0.26);
  EXPECT_DOUBLE_EQ(h[1].pitch->range_lo_deg.value(), -0.42);
  EXPECT_EQ(h[1].pitch->points.value(), 40);
  EXPECT_FALSE(h[1].yaw->sd_arcsec.has_value());
  EXPECT_EQ(h[1].coefficients, late.coefficients);  // the JSON comes back as it went in
  EXPECT_EQ(c->find_calibration(late_id)->unit, "SN-1");
  EXPECT_FALSE(c->find_calibration(late_id + 1000).has_value());
  EXPECT_EQ(c->run_calibrations("r1").size(), 1u);
}

TEST_P(Backends, StoresAcceptancesWithTheirCertificates) {
  auto c = open();
  c->record_run_start(make_run("r1", "SN-1"));
  AcceptanceRecord a;
  a.unit = "SN-1";
  a.run_id = "r1";
  a.passed = true;
  a.date_utc = "2024-05-01T12:00:00Z";
  a.certificate = {{"verdict", "pass"}, {"criteria", {1, 2, 3}}};
  a.stand = "stand-B";
  const int64_t id = c->record_acceptance(a);
  a.run_id = "nope";
  EXPECT_THROW(c->record_acceptance(a), std::invalid_argument);
  const auto acc = c->unit_acceptances("SN-1");
  ASSERT_EQ(acc.size(), 1u);
  EXPECT_EQ(acc[0].id, id);
  EXPECT_TRUE(acc[0].passed);
  EXPECT_EQ(acc[0].certificate["criteria"][2], 3);
  EXPECT_EQ(acc[0].stand, "stand-B");
  EXPECT_EQ(acc[0].host, this_host());
}

TEST_P(Backends, MigratesAnOlderSchemaAndRefusesANewerOne) {
  make_version_1();
  EXPECT_EQ(open(Catalogue::Mode::read_only)->schema_version(), Catalogue::kSchemaVersion);  // a read upgrades too
  {
    auto c = open();
    EXPECT_EQ(c->schema_version(), Catalogue::kSchemaVersion);
    EXPECT_TRUE(c->has_unit("OLD-1"));  // what was there stays
    c->record_run_start(make_run("r1", "OLD-1"));
    auto cal = CalibrationRecord::from_calibration_json(calibration_json("OLD-1", 0.3), "x");
    cal.source = "run";
    cal.run_id = "r1";
    cal.stand = "stand-C";
    c->record_calibration(cal);
    EXPECT_EQ(c->unit_history("OLD-1").at(0).stand, "stand-C");
  }
  set_version(Catalogue::kSchemaVersion + 7);
  for (auto mode : {Catalogue::Mode::read_write, Catalogue::Mode::read_only}) {
    const std::string msg = test::error_of<InputError>([&] { open(mode); });
    EXPECT_NE(msg.find(fmt::format("schema version {}", Catalogue::kSchemaVersion + 7)), std::string::npos) << msg;
    EXPECT_NE(msg.find("newer"), std::string::npos) << msg;
  }
}

// A catalogue of schema version 2 (no operators) gains the operator column on runs, calibrations and
// acceptances; what it held names none until the run's operator is recorded (as a rebuild does from
// run.json), and records made since carry theirs.
TEST_P(Backends, AVersion2CatalogueGainsTheOperatorOfEachRecord) {
  // SQL's quote within a string: each ' doubled (built anew rather than inserted in place, which GCC 12
  // misreads as an overlapping copy).
  std::string coefficients;
  for (const char ch : calibration_json("OLD-1", 0.3).dump()) {
    coefficients += ch;
    if (ch == '\'') coefficients += '\'';
  }
  make_version(2, fmt::format(
                      "INSERT INTO runs(run_id, unit, procedure, procedure_hash, started_utc, outcome, run_dir, emulated, "
                      "stand, software_version) VALUES('old-run', 'OLD-1', 'discrete_grid', 'sha256:0', "
                      "'2024-01-01T00:00:00Z', 'completed', '/runs/old-run', (1 = 0), 'stand-A', '0.9');"
                      "INSERT INTO calibrations(unit, source, run_id, source_ref, date_utc, recorded_utc, method, "
                      "coefficients_json, stand) VALUES('OLD-1', 'run', 'old-run', 'old-run', '2024-01-01T01:00:00Z', "
                      "'2024-01-01T01:00:00Z', 'differences', '{}', 'stand-A');"
                      "INSERT INTO acceptances(unit, run_id, passed, date_utc, recorded_utc, certificate_json, stand) "
                      "VALUES('OLD-1', 'old-run', (1 = 1), '2024-01-01T02:00:00Z', '2024-01-01T02:00:00Z', '{{}}', "
                      "'stand-A');",
                      coefficients));
  for (const char* table : {"runs", "calibrations", "acceptances"}) EXPECT_FALSE(has_column(table, "operator")) << table;
  auto c = open();
  EXPECT_EQ(c->schema_version(), 3);
  for (const char* table : {"runs", "calibrations", "acceptances"}) EXPECT_TRUE(has_column(table, "operator")) << table;
  EXPECT_EQ(c->find_run("old-run")->operator_name, "");
  EXPECT_EQ(c->unit_history("OLD-1").at(0).operator_name, "");
  EXPECT_EQ(c->unit_acceptances("OLD-1").at(0).operator_name, "");
  EXPECT_EQ(c->unit_history("OLD-1").at(0).stand, "stand-A");  // what was there stays
  // The run, its calibration and its acceptance: three records named; again, nothing changes.
  EXPECT_EQ(c->record_run_operator("old-run", "A. Ann"), 3);
  EXPECT_EQ(c->record_run_operator("old-run", "A. Ann"), 0);
  EXPECT_THROW(c->record_run_operator("no-such-run", "A. Ann"), std::invalid_argument);
  EXPECT_EQ(c->find_run("old-run")->operator_name, "A. Ann");
  EXPECT_EQ(c->unit_history("OLD-1").at(0).operator_name, "A. Ann");
  EXPECT_EQ(c->unit_acceptances("OLD-1").at(0).operator_name, "A. Ann");
  // New records carry theirs; a resume names whoever resumed it; a calibration already named keeps its operator.
  RunStart run = make_run("new-run", "OLD-1", "2024-02-01T00:00:00Z");
  run.operator_name = "B. Bo";
  c->record_run_start(run);
  EXPECT_EQ(c->find_run("new-run")->operator_name, "B. Bo");
  auto cal = CalibrationRecord::from_calibration_json(calibration_json("OLD-1", 0.3), "x");
  cal.source = "run";
  cal.run_id = "new-run";
  cal.date_utc = "2024-02-01T01:00:00Z";
  cal.operator_name = "B. Bo";
  c->record_calibration(cal);
  run.operator_name = "C. Cy";
  c->record_run_start(run);
  EXPECT_EQ(c->find_run("new-run")->operator_name, "C. Cy");
  EXPECT_EQ(c->find_run("new-run")->resumes, 1);
  EXPECT_EQ(c->record_run_operator("new-run", "C. Cy"), 0);  // the run has it; the calibration names B. Bo
  EXPECT_EQ(c->unit_history("OLD-1").at(1).operator_name, "B. Bo");
}

TEST_P(Backends, ReadOnlyRefusesWhatIsNoCatalogue) {
  if (GetParam() == Backend::postgresql) {
    const std::string msg = test::error_of<InputError>([&] { open(Catalogue::Mode::read_only); });
    EXPECT_NE(msg.find("not a stand catalogue"), std::string::npos) << msg;
  } else {
    EXPECT_THROW(open(Catalogue::Mode::read_only), InputError);  // no file
  }
  open();  // a writer creates the schema
  EXPECT_EQ(open(Catalogue::Mode::read_only)->schema_version(), Catalogue::kSchemaVersion);
}

// Processes writing at once, on a fresh catalogue (so they also race to create the schema):
// nothing lost, nothing duplicated, every row its writer's.
TEST_P(Backends, ConcurrentWritersLoseAndDuplicateNothing) {
  constexpr int kWriters = 6, kRunsEach = 15;
  const auto done = test::fork_together(kWriters, [&](int w) {
    auto cat = open();
    test::write_runs(*cat, w, kRunsEach, 3, 99, [](const std::string& id, const std::string& unit) {
      return make_run(id, unit);
    }, calibration_json);
  });
  for (int code : done.exit_codes) EXPECT_EQ(code, 0);
  auto c = open(Catalogue::Mode::read_only);
  const auto runs = c->list_runs();
  EXPECT_EQ(runs.size(), static_cast<size_t>(kWriters * kRunsEach));
  std::set<std::string> ids;
  for (const auto& r : runs) {
    ids.insert(r.run_id);
    EXPECT_EQ(r.outcome, RunOutcome::completed);
  }
  EXPECT_EQ(ids.size(), runs.size());
  std::set<int64_t> cal_ids;
  for (const auto& u : c->units()) {
    for (const auto& cal : c->unit_history(u)) {
      int w = -1, i = -1;
      ASSERT_TRUE(test::writer_of_run(cal.run_id.value(), w, i));
      EXPECT_NEAR(cal.pitch->mean_abs_arcsec.value(), test::writer_pitch_mean(w, i), 1e-12);
      EXPECT_TRUE(cal_ids.insert(cal.id).second);
    }
  }
  EXPECT_EQ(cal_ids.size(), static_cast<size_t>(kWriters * kRunsEach));
}

TEST_P(Backends, ConcurrentImportsOfOneFileRecordItOnce) {
  open();  // the schema first: this test is about the import, not the creation
  constexpr int kProcs = 6;
  const auto done = test::fork_together(kProcs, [&](int) {
    auto cat = open();
    for (const char* name : {"a-1-fpss1", "a-6-fpss1"}) {
      auto cal = CalibrationRecord::from_calibration_json(to_json(load_published(name)), name);
      cal.unit = "FPSS1";
      cal.source = "import";
      cal.source_ref = name;
      cal.date_utc = "2024-01-01";
      cat->record_import_once(cal);
    }
  });
  for (int code : done.exit_codes) EXPECT_EQ(code, 0);
  EXPECT_EQ(open()->unit_history("FPSS1").size(), 2u);
}

// copy to the other backend and back: everything arrives once, a second copy adds nothing.
TEST_P(Backends, CopiesToTheOtherBackendIdempotently) {
  auto src = open();
  RunStart r1_start = make_run("r1", "SN-1", "2024-05-01T10:00:00Z");
  r1_start.operator_name = "A. Ann";
  src->record_run_start(r1_start);
  src->record_run_end("r1", RunOutcome::completed, "2024-05-01T11:00:00Z");
  src->record_run_start(make_run("r2", "SN-1", "2024-05-02T10:00:00Z"));  // still running
  auto cal = CalibrationRecord::from_calibration_json(calibration_json("SN-1", 0.2), "x");
  cal.source = "run";
  cal.run_id = "r1";
  cal.date_utc = "2024-05-01T11:00:00Z";
  cal.operator_name = "A. Ann";
  src->record_calibration(cal);
  auto imp = CalibrationRecord::from_calibration_json(calibration_json("SN-1", 0.4), "y");
  imp.source = "import";
  imp.source_ref = "/somewhere/y.json";
  imp.date_utc = "2024-01-01";
  src->record_import_once(imp);
  AcceptanceRecord a;
  a.unit = "SN-1";
  a.run_id = "r1";
  a.passed = true;
  a.date_utc = "2024-05-01T11:00:00Z";
  a.operator_name = "A. Ann";
  src->record_acceptance(a);

  static std::atomic<int> n{0};
  const std::string other = GetParam() == Backend::sqlite
                                ? pg().create_database(fmt::format("copy{}_{}", ::getpid(), n++))
                                : "sqlite:" + (dir_.path() / "copy.db").string();
  {
    auto dst = open_catalogue(other);
    const CopyReport r = copy_catalogue(*src, *dst);
    EXPECT_EQ(r.runs_added, 2);
    EXPECT_EQ(r.calibrations_added, 2);
    EXPECT_EQ(r.acceptances_added, 1);
    const CopyReport again = copy_catalogue(*src, *dst);
    EXPECT_EQ(again.runs_added + again.calibrations_added + again.acceptances_added + again.units_added, 0);
  }
  auto dst = open_catalogue(other, Catalogue::Mode::read_only);
  const auto r1 = dst->find_run("r1").value();
  EXPECT_EQ(r1.ended_utc.value_or(""), "2024-05-01T11:00:00Z");
  EXPECT_EQ(r1.host, this_host());
  EXPECT_EQ(r1.operator_name, "A. Ann");
  EXPECT_EQ(dst->find_run("r2")->operator_name, "");
  EXPECT_TRUE(dst->find_run("r2")->running());
  const auto h = dst->unit_history("SN-1");
  ASSERT_EQ(h.size(), 2u);
  EXPECT_EQ(h[0].source, "import");
  EXPECT_EQ(h[1].run_id.value_or(""), "r1");
  EXPECT_EQ(h[1].coefficients, cal.coefficients);
  EXPECT_EQ(h[1].operator_name, "A. Ann");
  EXPECT_EQ(h[0].operator_name, "");
  EXPECT_EQ(dst->unit_acceptances("SN-1").size(), 1u);
  EXPECT_EQ(dst->unit_acceptances("SN-1").at(0).operator_name, "A. Ann");
}

// The commands over either backend through --catalogue URL, its alias --db, and FPSS_CATALOGUE.
TEST_P(Backends, CommandsTakeTheCatalogueUrlTheAliasAndTheEnvironment) {
  const fs::path coeffs = test::write_file(dir_.path() / "vi.json", to_json(load_published("a-6-fpss1")).dump());
  auto r = test::run_stand({"import", coeffs.string(), "--unit", "SN-7", "--date", "2024-02-03", "--catalogue", url_,
                            "--json"},
                           dir_.path(), "import");
  ASSERT_EQ(r.code, 0) << r.err;
  const int64_t id = nlohmann::json::parse(r.out)["id"].get<int64_t>();
  r = test::run_stand({"compare", fmt::format("cal:{}", id), "a-6-fpss1", "--db", url_, "--json"}, dir_.path(),
                      "compare");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_LT(nlohmann::json::parse(r.out)["alpha"]["max_abs_arcsec"].get<double>(), 1e-9);  // itself
  ::setenv("FPSS_CATALOGUE", url_.c_str(), 1);
  r = test::run_stand({"history", "SN-7", "--json"}, dir_.path(), "history");
  // An explicit --runs-dir still names its own stand.db (none there: exit 2).
  const auto other = test::run_stand({"history", "SN-7", "--runs-dir", (dir_.path() / "elsewhere").string()},
                                     dir_.path(), "other");
  ::unsetenv("FPSS_CATALOGUE");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["calibrations"].size(), 1u);
  EXPECT_EQ(other.code, 2) << other.err;
  EXPECT_NE(other.err.find("elsewhere"), std::string::npos) << other.err;
  // Without it, the default (RUNS_DIR/stand.db) does not exist: exit 2 naming it.
  r = test::run_stand({"history", "SN-7", "--runs-dir", (dir_.path() / "none").string()}, dir_.path(), "none");
  EXPECT_EQ(r.code, 2);
  const std::string copy = "sqlite:" + (dir_.path() / "copied.db").string();
  r = test::run_stand({"catalogue", "copy", "--from", url_, "--to", copy, "--json"}, dir_.path(), "copy");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["calibrations_added"], 1);
  EXPECT_EQ(open_catalogue(copy, Catalogue::Mode::read_only)->unit_history("SN-7").at(0).label, "V");
}

TEST_P(Backends, MsaStudiesUnitsByStandsFromEitherBackend) {
  // Three units x two stands x three repeats, plus one older calibration the --since leaves out.
  // C1 = 2 arcsec per unit + 0.3 per stand + 0.1 arcsec noise (seeded): the angle at zero counts moves with it.
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.1);
  GaugeStudy expected;
  {
    auto cat = open();
    expected.y.assign(3, std::vector<std::vector<double>>(2));
    for (int u = 0; u < 3; ++u) {
      const std::string unit = fmt::format("SN-{}", u);
      cat->add_unit(unit);
      for (int st = 0; st < 2; ++st) {
        for (int k = -1; k < 3; ++k) {
          const double c1_arcsec = 2.0 * u + 0.3 * st + noise(rng);
          const double pitch_mean = 0.3 + 0.01 * noise(rng);
          cat->record_calibration(msa_calibration(
              unit, c1_arcsec, pitch_mean, fmt::format("msa-{}-{}-{}.json", u, st, k), st == 0 ? "stand-A" : "stand-B",
              k < 0 ? "2025-06-01T00:00:00Z" : fmt::format("2026-02-0{}T00:00:00Z", k + 1)));
          if (k >= 0) expected.y[u][st].push_back(c1_arcsec);
        }
      }
    }
  }
  const fs::path out = dir_.path() / "msa.json", page = dir_.path() / "msa.html";
  auto r = test::run_stand({"msa", "--catalogue", url_, "--since", "2026-01-01", "--out", out.string(), "--report",
                            page.string()},
                           dir_.path(), "msa");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto m = nlohmann::json::parse(test::read_file(out));
  EXPECT_EQ(m["format"], "fpss-stand msa/1");
  EXPECT_EQ(m["appraisers"], "stands");  // the default
  EXPECT_FALSE(m.contains("operators"));
  EXPECT_EQ(m["selection"]["operators"], nlohmann::json::array());
  EXPECT_EQ(m["units"], nlohmann::json({"SN-0", "SN-1", "SN-2"}));
  EXPECT_EQ(m["stands"], nlohmann::json({"stand-A", "stand-B"}));
  EXPECT_EQ(m["repeats"], 3);
  EXPECT_EQ(m["records_used"], 18);
  EXPECT_EQ(m["records_left_out"], 6);
  const auto& q = m["quantities"]["angle_pitch_at_+0.0deg_arcsec"];
  const GaugeRr want = gauge_rr(expected, 10.0);  // tolerance: the 5 arcsec accuracy limit either side
  EXPECT_NEAR(q["sd"]["ev"].get<double>(), want.ev, 1e-6);
  EXPECT_NEAR(q["sd"]["av"].get<double>(), want.av, 1e-6);
  EXPECT_NEAR(q["grr_percent_tolerance"].get<double>(), *want.grr_percent_tolerance, 1e-4);
  EXPECT_EQ(q["ndc"], want.ndc);
  EXPECT_GT(want.av, 0.05);  // the 0.3 arcsec between stands shows as reproducibility
  EXPECT_EQ(q["tolerance"], 10.0);
  EXPECT_TRUE(m["quantities"].contains("angle_yaw_at_+0.4deg_arcsec"));
  EXPECT_TRUE(m["skipped"].contains("accuracy_3sigma_pitch_arcsec"));  // no acceptances recorded
  const std::string html = test::read_file(page);
  EXPECT_NE(html.find("<table id=\"msa\">"), std::string::npos);
  EXPECT_NE(html.find("angle_pitch_at_+0.0deg_arcsec"), std::string::npos);
  // The plan of such a study: per stand every unit once per round, in a seeded random order.
  const fs::path plan = dir_.path() / "plan.json";
  r = test::run_stand({"msa", "plan", "--units", "SN-0,SN-1,SN-2", "--stands", "stand-A,stand-B", "--repeats", "3",
                       "--out", plan.string()},
                      dir_.path(), "plan");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto p = nlohmann::json::parse(test::read_file(plan));
  EXPECT_EQ(p["runs"], 18);
  EXPECT_FALSE(p.contains("operators_jobs"));
  ASSERT_EQ(p["stands_jobs"].size(), 2u);
  for (const auto& st : p["stands_jobs"]) {
    ASSERT_EQ(st["jobs"].size(), 9u);
    for (size_t round = 0; round < 3; ++round) {
      std::set<std::string> seen;
      for (size_t k = 0; k < 3; ++k) {
        const auto& job = st["jobs"][round * 3 + k];
        seen.insert(job["unit"].get<std::string>());
        EXPECT_EQ(job["round"], round + 1);
        EXPECT_FALSE(job.contains("operator")) << job.dump();  // whoever runs it: the catalogue records them
      }
      EXPECT_EQ(seen.size(), 3u) << "round " << round;
    }
  }
  r = test::run_stand({"msa", "plan", "--units", "SN-0,,SN-2", "--stands", "stand-A,stand-B", "--out", plan.string()},
                      dir_.path(), "plan-bad");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--units SN-0,,SN-2: an empty name in the list"), std::string::npos) << r.err;
  // One stand is no crossed study: exit 2, saying why.
  r = test::run_stand({"msa", "--catalogue", url_, "--stands", "stand-A", "--out", out.string()}, dir_.path(), "one");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("at least two units and two stands"), std::string::npos) << r.err;
}

// The operators as the appraisers: three units x two operators x three repeats, each operator on
// both stands alike, operator Bo reading 0.5 arcsec more than Ann; one record names no operator.
TEST_P(Backends, MsaStudiesUnitsByOperatorsFromEitherBackend) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.1);
  const char* const operators[] = {"Ann", "Bo"};
  GaugeStudy expected;  // [unit][operator][repeat]
  {
    auto cat = open();
    expected.y.assign(3, std::vector<std::vector<double>>(2));
    const auto record = [&](int u, const std::string& op, const std::string& stand, const std::string& date, double c1) {
      const std::string unit = fmt::format("SN-{}", u);
      auto cal = msa_calibration(unit, c1, 0.3 + 0.01 * noise(rng), fmt::format("msa-{}-{}-{}.json", u, op, date), stand,
                                 date);
      cal.operator_name = op;
      cat->record_calibration(cal);
    };
    for (int u = 0; u < 3; ++u) {
      for (int o = 0; o < 2; ++o) {
        for (int k = 0; k < 3; ++k) {
          const double c1_arcsec = 2.0 * u + 0.5 * o + noise(rng);
          record(u, operators[o], k % 2 == 0 ? "stand-A" : "stand-B", fmt::format("2026-02-0{}T00:00:00Z", k + 1),
                 c1_arcsec);
          expected.y[u][o].push_back(c1_arcsec);
        }
      }
    }
    record(0, "", "stand-A", "2026-03-01T00:00:00Z", 0.0);  // a run that named no operator
  }
  const fs::path out = dir_.path() / "msa-ops.json", page = dir_.path() / "msa-ops.html";
  // Every operator: the one record naming none makes operator "unnamed", whose cells are short.
  auto r = test::run_stand({"msa", "--catalogue", url_, "--appraisers", "operators", "--out", out.string()},
                           dir_.path(), "msa-unnamed");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("at least two calibrations by every operator"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("SN-0 by operator unnamed (1); SN-1 by operator unnamed (0)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("catalogue rebuild"), std::string::npos) << r.err;
  r = test::run_stand({"msa", "--catalogue", url_, "--appraisers", "operators", "--operators", "Ann,Bo", "--out",
                       out.string(), "--report", page.string()},
                      dir_.path(), "msa-ops");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("3 units x 2 operators x 3 repeats"), std::string::npos) << r.out;
  const auto m = nlohmann::json::parse(test::read_file(out));
  EXPECT_EQ(m["appraisers"], "operators");
  EXPECT_EQ(m["operators"], nlohmann::json({"Ann", "Bo"}));
  EXPECT_FALSE(m.contains("stands"));
  EXPECT_EQ(m["selection"]["operators"], nlohmann::json({"Ann", "Bo"}));
  EXPECT_EQ(m["repeats"], 3);
  EXPECT_EQ(m["records_used"], 18);
  EXPECT_EQ(m["records_left_out"], 1);  // the unnamed one
  const auto& q = m["quantities"]["angle_pitch_at_+0.0deg_arcsec"];
  ASSERT_EQ(q["values"].size(), 3u);
  ASSERT_EQ(q["values"][0].size(), 2u);  // [unit][operator][repeat]
  const GaugeRr want = gauge_rr(expected, 10.0);
  EXPECT_NEAR(q["sd"]["ev"].get<double>(), want.ev, 1e-6);
  EXPECT_NEAR(q["sd"]["av"].get<double>(), want.av, 1e-6);
  EXPECT_NEAR(q["grr_percent_tolerance"].get<double>(), *want.grr_percent_tolerance, 1e-4);
  EXPECT_EQ(q["ndc"], want.ndc);
  EXPECT_GT(want.av, 0.2);  // the 0.5 arcsec between operators (two of them: 0.35) shows as reproducibility
  // Bo's mean minus Ann's, over units and repeats: the offset put in, within the noise.
  double d = 0;
  for (int u = 0; u < 3; ++u) {
    for (int k = 0; k < 3; ++k) d += (q["values"][u][1][k].get<double>() - q["values"][u][0][k].get<double>()) / 9;
  }
  EXPECT_NEAR(d, 0.5, 0.15);
  const std::string html = test::read_file(page);
  EXPECT_NE(html.find("2 operators (Ann, Bo)"), std::string::npos);
  EXPECT_NE(html.find("the appraisers are the operators"), std::string::npos);
  // The same records with the stands as the appraisers: each stand saw both operators, so the
  // operators' offset is no stand effect; it is scatter within the cells (repeatability) instead.
  const fs::path by_stands = dir_.path() / "msa-stands.json";
  r = test::run_stand({"msa", "--catalogue", url_, "--operators", "Ann,Bo", "--out", by_stands.string()}, dir_.path(),
                      "msa-stands");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto st = nlohmann::json::parse(test::read_file(by_stands));
  EXPECT_EQ(st["appraisers"], "stands");
  EXPECT_EQ(st["stands"], nlohmann::json({"stand-A", "stand-B"}));
  const auto& sq = st["quantities"]["angle_pitch_at_+0.0deg_arcsec"];
  EXPECT_LT(sq["sd"]["av"].get<double>(), 0.5 * want.av);
  EXPECT_GT(sq["sd"]["ev"].get<double>(), want.ev + 0.1);
  std::printf("by operators: EV %.4f AV %.4f %%GRR of the tolerance %.2f (the ANOVA of the values: EV %.4f AV %.4f "
              "%.2f); Bo - Ann %.3f arcsec; by stands: EV %.4f AV %.4f\n",
              q["sd"]["ev"].get<double>(), q["sd"]["av"].get<double>(), q["grr_percent_tolerance"].get<double>(), want.ev,
              want.av, *want.grr_percent_tolerance, d, sq["sd"]["ev"].get<double>(), sq["sd"]["av"].get<double>());
  // One operator is no crossed study: exit 2 naming the operators.
  r = test::run_stand({"msa", "--catalogue", url_, "--appraisers", "operators", "--operators", "Bo", "--out",
                       out.string()},
                      dir_.path(), "msa-one");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("at least two units and two operators; the selection has 3 unit(s) (SN-0, SN-1, SN-2) and 1 "
                       "operator(s) (Bo)"),
            std::string::npos)
      << r.err;
  // The plan of such a study: per operator every unit once per round, each job naming its operator.
  const fs::path plan = dir_.path() / "plan-ops.json";
  r = test::run_stand({"msa", "plan", "--units", "SN-0,SN-1,SN-2", "--operators", "Ann,Bo", "--repeats", "3", "--out",
                       plan.string()},
                      dir_.path(), "plan-ops");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("18 runs: 9 per operator"), std::string::npos) << r.out;
  const auto p = nlohmann::json::parse(test::read_file(plan));
  EXPECT_EQ(p["runs"], 18);
  EXPECT_EQ(p["operators"], nlohmann::json({"Ann", "Bo"}));
  EXPECT_FALSE(p.contains("stands_jobs"));
  ASSERT_EQ(p["operators_jobs"].size(), 2u);
  for (size_t o = 0; o < 2; ++o) {
    const auto& entry = p["operators_jobs"][o];
    EXPECT_EQ(entry["operator"], operators[o]);
    ASSERT_EQ(entry["jobs"].size(), 9u);
    for (size_t round = 0; round < 3; ++round) {
      std::set<std::string> seen;
      for (size_t k = 0; k < 3; ++k) {
        const auto& job = entry["jobs"][round * 3 + k];
        seen.insert(job["unit"].get<std::string>());
        EXPECT_EQ(job["operator"], operators[o]);
        EXPECT_EQ(job["kind"], "run");
      }
      EXPECT_EQ(seen.size(), 3u) << "round " << round;
    }
  }
  // Stands or operators: one of them.
  r = test::run_stand({"msa", "plan", "--units", "SN-0,SN-1", "--stands", "S1,S2", "--operators", "Ann,Bo", "--out",
                       plan.string()},
                      dir_.path(), "plan-both");
  EXPECT_EQ(r.code, 2) << r.err;
  r = test::run_stand({"msa", "plan", "--units", "SN-0,SN-1", "--out", plan.string()}, dir_.path(), "plan-neither");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("--stands or --operators"), std::string::npos) << r.err;
  r = test::run_stand({"msa", "plan", "--units", "SN-0,SN-1", "--operators", "Ann", "--out", plan.string()},
                      dir_.path(), "plan-one");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("--units and --operators need at least two names each"), std::string::npos) << r.err;
}

INSTANTIATE_TEST_SUITE_P(Catalogue, Backends, ::testing::Values(Backend::sqlite, Backend::postgresql),
                         [](const auto& info) { return info.param == Backend::sqlite ? "sqlite" : "postgresql"; });

// Staleness needs the run's own host: a pid of another host is never judged from here.
TEST(RunRecord, IsStaleOnlyOnItsOwnHostWithItsProcessGone) {
  RunRecord r;
  r.outcome.reset();  // running
  r.host = this_host();
  r.pid = ::getpid();
  EXPECT_FALSE(r.stale());
  const pid_t child = fork_child([] {});
  test::wait_exit_code(child);
  r.pid = child;  // reaped: gone
  EXPECT_TRUE(r.stale());
  r.host = this_host() + "-elsewhere";
  EXPECT_FALSE(r.stale());
}

// With its run folder on this host, a run is alive while a process holds the folder's lock, the
// one the run takes before it writes anything: a live process that merely has the run's pid (pids
// are reused) does not make a killed run alive.
TEST(RunRecord, IsStaleWhenNoProcessHoldsItsFoldersLockWhateverHasItsPid) {
  test::TempDir dir;
  RunRecord r;
  r.outcome.reset();  // running
  r.host = this_host();
  r.pid = ::getpid();  // alive, as a reused pid would be
  r.run_dir = dir.path().string();
  EXPECT_FALSE(run_folder_owned(dir.path()));  // no lock file: this host cannot tell
  EXPECT_FALSE(r.stale());                     // and the pid says alive
  test::write_file(dir.path() / ".lock", "");
  EXPECT_EQ(run_folder_owned(dir.path()), false);
  EXPECT_TRUE(r.stale());
  UniqueFd fd(::open((dir.path() / ".lock").c_str(), O_RDWR | O_CLOEXEC));
  ASSERT_TRUE(fd);
  ASSERT_EQ(::flock(fd.get(), LOCK_EX | LOCK_NB), 0);
  EXPECT_EQ(run_folder_owned(dir.path()), true);
  EXPECT_FALSE(r.stale());
  fd.reset();  // the owner gone, however: the kernel drops its lock
  EXPECT_TRUE(r.stale());
}

TEST(OpenCatalogue, ChoosesTheBackendByUrlAndHidesPasswords) {
  test::TempDir dir;
  const auto plain = open_catalogue((dir.path() / "a.db").string());
  EXPECT_EQ(plain->backend(), "sqlite");
  EXPECT_EQ(open_catalogue("sqlite:" + (dir.path() / "b.db").string())->backend(), "sqlite");
  EXPECT_TRUE(fs::exists(dir.path() / "b.db"));
  EXPECT_THROW(open_catalogue("mysql://x/y"), InputError);
  EXPECT_THROW(open_catalogue(""), InputError);
  EXPECT_TRUE(is_postgres_url("postgres://u@h/db"));
  EXPECT_EQ(url_for_messages("postgresql://stand:s3cret@db.example:5432/fpss?sslmode=require"),
            "postgresql://stand@db.example:5432/fpss?sslmode=require");
  // A server that is not there: an error naming it, within the retry window, not a hang.
  const int port = test::free_loopback_port();
  const std::string msg = test::error_of<CatalogueUnavailable>(
      [&] { PostgresCatalogue c(fmt::format("postgresql://x@127.0.0.1:{}/none?connect_timeout=2", port)); });
  EXPECT_NE(msg.find("cannot connect"), std::string::npos) << msg;
}

}  // namespace
}  // namespace fpss
