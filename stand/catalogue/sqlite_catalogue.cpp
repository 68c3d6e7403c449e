// The SQLite backend of the catalogue: one file, WAL, short IMMEDIATE transactions.
#include "stand/catalogue/sqlite_catalogue.h"
#include "stand/catalogue/record_rules.h"

#include "procedures/recorder.h"

#include <fmt/format.h>
#include <signal.h>
#include <unistd.h>

#include <SQLiteCpp/SQLiteCpp.h>
#include <sqlite3.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <ctime>
#include <functional>
#include <initializer_list>
#include <stdexcept>
#include <thread>

#include "calib/coefficients.h"
#include "calib/errors.h"
#include "stand/catalogue/schema.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const fs::path& path, const std::string& what, const SQLite::Exception& e) {
  // SQLITE_NOTADB (26) and SQLITE_CORRUPT (11) are about the file the user named.
  const int code = e.getErrorCode();
  if (code == SQLITE_NOTADB || code == SQLITE_CORRUPT || code == SQLITE_CANTOPEN) {
    throw InputError(fmt::format("{}: {}: {}", path.string(), what, e.what()));
  }
  throw std::runtime_error(fmt::format("{}: {}: {}", path.string(), what, e.what()));
}

// Runs `body` in a BEGIN IMMEDIATE transaction: the write lock is taken up front, so the busy
// timeout applies (a deferred transaction upgrading to a writer gets SQLITE_BUSY at once).
template <typename F>
auto write_txn(SQLite::Database& db, F&& body) {
  SQLite::Transaction txn(db, SQLite::TransactionBehavior::IMMEDIATE);
  if constexpr (std::is_void_v<decltype(body())>) {
    body();
    txn.commit();
  } else {
    auto r = body();
    txn.commit();
    return r;
  }
}

// Runs `body`; an SQLite error becomes fail()'s, naming the file and what was being done.
template <typename F>
auto guarded(const fs::path& path, const std::string& what, F&& body) {
  try {
    return body();
  } catch (const SQLite::Exception& e) {
    fail(path, what, e);
  }
}

template <typename T>
void bind_opt(SQLite::Statement& st, const std::string& name, const std::optional<T>& v) {
  if (v) st.bind(name, *v);
  else st.bind(name);
}

// Text parameters, bound by name.
void bind_texts(SQLite::Statement& st, std::initializer_list<std::pair<const char*, const std::string&>> texts) {
  for (const auto& [name, text] : texts) st.bind(name, text);
}

// The residual columns of one axis, bound by name.
void bind_stats(SQLite::Statement& st, const std::string& axis, const std::optional<AxisResidualStats>& s) {
  const auto p = ":" + axis + "_";
  const AxisResidualStats none;
  const AxisResidualStats& v = s ? *s : none;
  bind_opt(st, p + "mean_abs_arcsec", v.mean_abs_arcsec);
  bind_opt(st, p + "sd_arcsec", v.sd_arcsec);
  bind_opt(st, p + "max_abs_arcsec", v.max_abs_arcsec);
  bind_opt(st, p + "rms_arcsec", v.rms_arcsec);
  bind_opt(st, p + "points", v.points);
  bind_opt(st, p + "range_lo_deg", v.range_lo_deg);
  bind_opt(st, p + "range_hi_deg", v.range_hi_deg);
}

// A statement's current row, read by column name for the shared record readers (record_rules.h).
struct SqliteRow {
  SQLite::Statement& st;

  SQLite::Column col(const std::string& c) const { return st.getColumn(c.c_str()); }
  std::string text(const std::string& c) const { return col(c).getString(); }
  int64_t integer(const std::string& c) const { return col(c).getInt64(); }
  bool flag(const std::string& c) const { return col(c).getInt() != 0; }
  std::optional<std::string> opt_text(const std::string& c) const {
    if (col(c).isNull()) return std::nullopt;
    return text(c);
  }
  std::optional<int64_t> opt_integer(const std::string& c) const {
    if (col(c).isNull()) return std::nullopt;
    return integer(c);
  }
  std::optional<double> opt_real(const std::string& c) const {
    if (col(c).isNull()) return std::nullopt;
    return col(c).getDouble();
  }
};

// Every row the statement gives, as records.
template <typename Record>
std::vector<Record> all_rows(SQLite::Statement& st, Record (*read)(const SqliteRow&)) {
  std::vector<Record> out;
  while (st.executeStep()) out.push_back(read(SqliteRow{st}));
  return out;
}

// The records `sql` selects with `key` as its one parameter: all of them, or the first (if any).
template <typename Record, typename Key>
std::vector<Record> select_all(SQLite::Database& db, const std::string& sql, const Key& key,
                               Record (*read)(const SqliteRow&)) {
  SQLite::Statement st(db, sql);
  st.bind(1, key);
  return all_rows(st, read);
}
template <typename Record, typename Key>
std::optional<Record> select_first(SQLite::Database& db, const std::string& sql, const Key& key,
                                   Record (*read)(const SqliteRow&)) {
  SQLite::Statement st(db, sql);
  st.bind(1, key);
  if (!st.executeStep()) return std::nullopt;
  return read(SqliteRow{st});
}

bool insert_unit(SQLite::Database& db, const std::string& serial) {
  SQLite::Statement st(db, "INSERT OR IGNORE INTO units(serial, first_seen_utc) VALUES(?, ?)");
  st.bind(1, serial);
  st.bind(2, utc_now_iso());
  return st.exec() == 1;
}

bool run_exists(SQLite::Database& db, const std::string& run_id) {
  SQLite::Statement st(db, "SELECT 1 FROM runs WHERE run_id = ?");
  st.bind(1, run_id);
  return st.executeStep();
}

}  // namespace

SqliteCatalogue::SqliteCatalogue(const fs::path& path, Mode mode, int busy_timeout_ms) : path_(path) {
  const bool ro = mode == Mode::read_only;
  if (ro && !fs::exists(path_)) {
    throw InputError(fmt::format("{}: no catalogue there (no run has been recorded with it)", path_.string()));
  }
  if (!ro && path_.has_parent_path()) fs::create_directories(path_.parent_path());
  try {
    db_ = std::make_unique<SQLite::Database>(
        path_, ro ? SQLite::OPEN_READONLY : (SQLite::OPEN_READWRITE | SQLite::OPEN_CREATE), busy_timeout_ms);
    db_->exec("PRAGMA foreign_keys = ON");
    if (!ro) {
      // Switching to WAL takes an exclusive lock that the busy handler does not always wait for
      // when another process is creating the file at the same moment: retry within the timeout.
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(busy_timeout_ms);
      for (;;) {
        try {
          const std::string jm = db_->execAndGet("PRAGMA journal_mode = WAL").getString();
          if (jm != "wal") throw std::runtime_error(fmt::format("{}: journal mode stays \"{}\"", path_.string(), jm));
          break;
        } catch (const SQLite::Exception& e) {
          if ((e.getErrorCode() & 0xff) != SQLITE_BUSY && (e.getErrorCode() & 0xff) != SQLITE_LOCKED) throw;
          if (std::chrono::steady_clock::now() > deadline) throw;
          std::this_thread::sleep_for(std::chrono::milliseconds(5));
        }
      }
      // FULL: a committed catalogue row survives a power cut too, not only a killed process.
      db_->exec("PRAGMA synchronous = FULL");
      init_schema();
    } else {
      const int v = schema_version();
      if (v == 0) {
        throw InputError(fmt::format("{}: not a stand catalogue (no schema)", path_.string()));
      }
      if (v > kSchemaVersion) {
        throw InputError(fmt::format("{}: catalogue schema version {} is newer than this fpss-stand ({})",
                                     path_.string(), v, kSchemaVersion));
      }
      if (v != kSchemaVersion) {
        // Migrations apply on first use, a read included: upgrade through a writer, then read.
        try {
          SqliteCatalogue upgrade(path_, Mode::read_write, busy_timeout_ms);
        } catch (const std::exception& e) {
          throw InputError(fmt::format("{}: catalogue schema version {} must be upgraded to {} and cannot be: {}",
                                       path_.string(), v, kSchemaVersion, e.what()));
        }
      }
    }
  } catch (const SQLite::Exception& e) {
    fail(path_, "cannot open the catalogue", e);
  }
}

SqliteCatalogue::~SqliteCatalogue() = default;

int SqliteCatalogue::schema_version() const { return db_->execAndGet("PRAGMA user_version").getInt(); }

// The missing migrations run inside the IMMEDIATE transaction that also sets user_version, so two
// processes opening a fresh file at once cannot both create it, and a crash leaves the version
// before or after.
void SqliteCatalogue::init_schema() {
  if (schema_version() == kSchemaVersion) return;  // the common case: no write lock needed
  write_txn(*db_, [&] {
    const int v = schema_version();  // again, under the lock: another process may have done it
    if (v > kSchemaVersion) {
      throw InputError(fmt::format("{}: catalogue schema version {} is newer than this fpss-stand ({})",
                                   path_.string(), v, kSchemaVersion));
    }
    for (int step = v; step < kSchemaVersion; ++step) db_->exec(schema::migration(step, schema::Dialect::sqlite));
    db_->exec(fmt::format("PRAGMA user_version = {}", kSchemaVersion));
  });
}

bool SqliteCatalogue::add_unit(const std::string& serial) {
  require_unit(serial);
  return guarded(path_, "cannot add unit " + serial,
                 [&] { return write_txn(*db_, [&] { return insert_unit(*db_, serial); }); });
}

void SqliteCatalogue::record_run_start(const RunStart& start) {
  check_run_start(start);
  guarded(path_, "cannot record the start of run " + start.run_id, [&] {
    write_txn(*db_, [&] {
      {
        SQLite::Statement q(*db_, "SELECT unit FROM runs WHERE run_id = ?");
        q.bind(1, start.run_id);
        if (q.executeStep() && q.getColumn(0).getString() != start.unit) {
          throw std::invalid_argument(fmt::format("run {} belongs to unit {}, not {}", start.run_id,
                                                  q.getColumn(0).getString(), start.unit));
        }
      }
      insert_unit(*db_, start.unit);
      const RunStart run = as_recorded(start);
      SQLite::Statement st(*db_, R"sql(
        INSERT INTO runs(run_id, unit, procedure, procedure_hash, started_utc, outcome, run_dir,
                         emulated, stand, software_version, pid, host)
        VALUES(:run_id, :unit, :procedure, :hash, :started, 'running', :dir, :emulated, :stand,
               :version, :pid, :host)
        ON CONFLICT(run_id) DO UPDATE SET
          outcome = 'running', ended_utc = NULL, resumes = resumes + 1,
          pid = excluded.pid, host = excluded.host, software_version = excluded.software_version)sql");
      bind_texts(st, {{":run_id", run.run_id}, {":unit", run.unit}, {":procedure", run.procedure},
                      {":hash", run.procedure_hash}, {":started", run.started_utc}, {":dir", run.run_dir.string()},
                      {":stand", run.stand}, {":version", run.software_version}, {":host", this_host()}});
      st.bind(":emulated", run.emulated ? 1 : 0);
      st.bind(":pid", static_cast<int64_t>(::getpid()));
      st.exec();
    });
  });
}

void SqliteCatalogue::record_run_end(const std::string& run_id, const std::string& outcome,
                                     const std::string& ended_utc) {
  check_run_end(outcome);
  guarded(path_, "cannot record the end of run " + run_id, [&] {
    write_txn(*db_, [&] {
      SQLite::Statement st(*db_, "UPDATE runs SET ended_utc = ?, outcome = ? WHERE run_id = ?");
      st.bind(1, ended_utc.empty() ? utc_now_iso() : ended_utc);
      st.bind(2, outcome);
      st.bind(3, run_id);
      if (st.exec() != 1) throw std::invalid_argument(fmt::format("record_run_end: no run {}", run_id));
    });
  });
}

bool SqliteCatalogue::copy_run(const RunRecord& r) {
  require_unit(r.unit);
  return guarded(path_, "cannot copy run " + r.run_id, [&] {
    return write_txn(*db_, [&] {
      insert_unit(*db_, r.unit);
      SQLite::Statement st(*db_, fmt::format("INSERT OR IGNORE INTO runs({}) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                                             kRunColumns));
      st.bind(1, r.run_id);
      st.bind(2, r.unit);
      st.bind(3, r.procedure);
      st.bind(4, r.procedure_hash);
      st.bind(5, r.started_utc);
      if (r.ended_utc) st.bind(6, *r.ended_utc);
      else st.bind(6);
      st.bind(7, r.outcome);
      st.bind(8, r.run_dir);
      st.bind(9, r.emulated ? 1 : 0);
      st.bind(10, r.stand);
      st.bind(11, r.software_version);
      st.bind(12, r.resumes);
      st.bind(13, r.pid);
      st.bind(14, r.host);
      return st.exec() == 1;
    });
  });
}

namespace {

// The insert itself, inside the caller's transaction.
int64_t insert_calibration(SQLite::Database& db, const CalibrationRecord& given) {
  if (given.run_id && !run_exists(db, *given.run_id)) {
    throw std::invalid_argument(fmt::format("record_calibration: no run {}", *given.run_id));
  }
  insert_unit(db, given.unit);
  const CalibrationRecord cal = as_recorded(given);
  static const std::string sql = fmt::format(
      "INSERT INTO calibrations(unit, source, run_id, source_ref, label, date_utc, recorded_utc, method, "
      "coefficients_json, stand, host, {}) VALUES(:unit, :source, :run_id, :source_ref, :label, :date, :recorded, "
      ":method, :coefficients, :stand, :host, {})",
      stat_columns(), stat_columns(":{}_{}"));
  SQLite::Statement st(db, sql);
  bind_texts(st, {{":unit", cal.unit}, {":source", cal.source}, {":source_ref", cal.source_ref}, {":label", cal.label},
                  {":date", cal.date_utc}, {":recorded", cal.recorded_utc}, {":method", cal.method},
                  {":coefficients", cal.coefficients.dump()}, {":stand", cal.stand}, {":host", cal.host}});
  bind_opt(st, ":run_id", cal.run_id);
  bind_stats(st, "pitch", cal.pitch);
  bind_stats(st, "yaw", cal.yaw);
  st.exec();
  return db.getLastInsertRowid();
}

}  // namespace

int64_t SqliteCatalogue::record_calibration(const CalibrationRecord& cal) {
  check_calibration(cal);
  return guarded(path_, "cannot record a calibration of " + cal.unit,
                 [&] { return write_txn(*db_, [&] { return insert_calibration(*db_, cal); }); });
}

std::pair<int64_t, bool> SqliteCatalogue::record_import_once(const CalibrationRecord& cal) {
  check_import(cal);
  return guarded(path_, "cannot import a calibration of " + cal.unit, [&] {
    return write_txn(*db_, [&]() -> std::pair<int64_t, bool> {
      SQLite::Statement q(*db_,
                          "SELECT id FROM calibrations WHERE unit = ? AND source = 'import' AND date_utc = ? "
                          "AND coefficients_json = ? ORDER BY id LIMIT 1");
      q.bind(1, cal.unit);
      q.bind(2, cal.date_utc);
      q.bind(3, cal.coefficients.dump());
      if (q.executeStep()) return {q.getColumn(0).getInt64(), false};
      return {insert_calibration(*db_, cal), true};
    });
  });
}

int64_t SqliteCatalogue::record_acceptance(const AcceptanceRecord& given) {
  require_unit(given.unit);
  return guarded(path_, "cannot record an acceptance of " + given.unit, [&] {
    return write_txn(*db_, [&]() -> int64_t {
      if (given.run_id && !run_exists(*db_, *given.run_id)) {
        throw std::invalid_argument(fmt::format("record_acceptance: no run {}", *given.run_id));
      }
      insert_unit(*db_, given.unit);
      const AcceptanceRecord acc = as_recorded(given);
      SQLite::Statement st(*db_, R"sql(
        INSERT INTO acceptances(unit, run_id, passed, date_utc, recorded_utc, certificate_json, stand, host)
        VALUES(?, ?, ?, ?, ?, ?, ?, ?))sql");
      st.bind(1, acc.unit);
      if (acc.run_id) st.bind(2, *acc.run_id);
      else st.bind(2);
      st.bind(3, acc.passed ? 1 : 0);
      st.bind(4, acc.date_utc);
      st.bind(5, acc.recorded_utc);
      st.bind(6, acc.certificate.dump());
      st.bind(7, acc.stand);
      st.bind(8, acc.host);
      st.exec();
      return db_->getLastInsertRowid();
    });
  });
}

std::vector<std::string> SqliteCatalogue::units() const {
  return guarded(path_, "cannot list units", [&] {
    std::vector<std::string> out;
    SQLite::Statement st(*db_, "SELECT serial FROM units ORDER BY serial");
    while (st.executeStep()) out.push_back(st.getColumn(0).getString());
    return out;
  });
}

bool SqliteCatalogue::has_unit(const std::string& serial) const {
  return guarded(path_, "cannot look up unit " + serial, [&] {
    SQLite::Statement st(*db_, "SELECT 1 FROM units WHERE serial = ?");
    st.bind(1, serial);
    return st.executeStep();
  });
}

std::vector<RunRecord> SqliteCatalogue::list_runs(const RunFilter& filter) const {
  return guarded(path_, "cannot list runs", [&] {
    std::string sql = fmt::format("SELECT {} FROM runs", kRunColumns);
    if (filter.unit) sql += " WHERE unit = :unit";
    sql += " ORDER BY started_utc DESC, rowid DESC";
    if (filter.limit) sql += " LIMIT :limit";
    SQLite::Statement st(*db_, sql);
    if (filter.unit) st.bind(":unit", *filter.unit);
    if (filter.limit) st.bind(":limit", static_cast<int64_t>(filter.limit));
    return all_rows(st, run_of_row<SqliteRow>);
  });
}

std::optional<RunRecord> SqliteCatalogue::find_run(const std::string& run_id) const {
  return guarded(path_, "cannot look up run " + run_id, [&] {
    const auto sql = fmt::format("SELECT {} FROM runs WHERE run_id = ?", kRunColumns);
    return select_first(*db_, sql, run_id, run_of_row<SqliteRow>);
  });
}

std::vector<CalibrationRecord> SqliteCatalogue::unit_history(const std::string& serial) const {
  return guarded(path_, "cannot read the history of " + serial, [&] {
    const auto sql =
        fmt::format("SELECT {} FROM calibrations WHERE unit = ? ORDER BY date_utc, id", calibration_columns());
    return select_all(*db_, sql, serial, calibration_of_row<SqliteRow>);
  });
}

std::optional<CalibrationRecord> SqliteCatalogue::find_calibration(int64_t id) const {
  return guarded(path_, fmt::format("cannot look up calibration {}", id), [&] {
    const auto sql = fmt::format("SELECT {} FROM calibrations WHERE id = ?", calibration_columns());
    return select_first(*db_, sql, id, calibration_of_row<SqliteRow>);
  });
}

std::vector<CalibrationRecord> SqliteCatalogue::run_calibrations(const std::string& run_id) const {
  return guarded(path_, "cannot read the calibrations of run " + run_id, [&] {
    const auto sql = fmt::format("SELECT {} FROM calibrations WHERE run_id = ? ORDER BY id", calibration_columns());
    return select_all(*db_, sql, run_id, calibration_of_row<SqliteRow>);
  });
}

std::vector<AcceptanceRecord> SqliteCatalogue::unit_acceptances(const std::string& serial) const {
  return guarded(path_, "cannot read the acceptances of " + serial, [&] {
    const auto sql = fmt::format("SELECT {} FROM acceptances WHERE unit = ? ORDER BY date_utc, id", kAcceptanceColumns);
    return select_all(*db_, sql, serial, acceptance_of_row<SqliteRow>);
  });
}

std::string SqliteCatalogue::integrity_check() const {
  try {
    std::string out;
    SQLite::Statement st(*db_, "PRAGMA integrity_check");
    while (st.executeStep()) {
      if (!out.empty()) out += "\n";
      out += st.getColumn(0).getString();
    }
    return out;
  } catch (const SQLite::Exception& e) {
    return fmt::format("integrity_check failed: {}", e.what());
  }
}

}  // namespace fpss
