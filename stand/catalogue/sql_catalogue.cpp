// The catalogue's reads and writes, once for SQLite and PostgreSQL: the checks, the statements (each
// dialect's spelling where the two differ) and the records read back.
#include "stand/catalogue/sql_catalogue.h"

#include <fmt/format.h>
#include <unistd.h>

#include <stdexcept>

#include "base/clock.h"
#include "procedures/recorder.h"
#include "stand/catalogue/record_rules.h"

namespace fpss {
namespace {

using schema::Dialect;

// The n-th positional parameter (from 1): `?` in SQLite, `$n` in PostgreSQL.
std::string param(Dialect d, int n) { return d == Dialect::sqlite ? "?" : fmt::format("${}", n); }

// Parameters 1 to n, comma-separated.
std::string params(Dialect d, int n) {
  std::string out;
  for (int k = 1; k <= n; ++k) out += (k == 1 ? "" : ", ") + param(d, k);
  return out;
}

// An INSERT of `n` values into `table_columns` that leaves a row whose `key` exists as it is.
std::string insert_if_new(Dialect d, const std::string& table_columns, const std::string& key, int n) {
  if (d == Dialect::sqlite) return fmt::format("INSERT OR IGNORE INTO {} VALUES({})", table_columns, params(d, n));
  return fmt::format("INSERT INTO {} VALUES({}) ON CONFLICT ({}) DO NOTHING", table_columns, params(d, n), key);
}

// A run started again (resumed) keeps its start and counts the resume. SQLite names its parameters.
const char* const kSqliteStartRun = R"sql(
        INSERT INTO runs(run_id, unit, procedure, procedure_hash, started_utc, outcome, run_dir,
                         emulated, stand, software_version, pid, host, operator)
        VALUES(:run_id, :unit, :procedure, :hash, :started, 'running', :dir, :emulated, :stand,
               :version, :pid, :host, :operator)
        ON CONFLICT(run_id) DO UPDATE SET
          outcome = 'running', ended_utc = NULL, resumes = resumes + 1,
          pid = excluded.pid, host = excluded.host, software_version = excluded.software_version,
          operator = excluded.operator)sql";
const char* const kPostgresStartRun = R"sql(
      INSERT INTO runs(run_id, unit, procedure, procedure_hash, started_utc, outcome, run_dir,
                       emulated, stand, software_version, pid, host, operator)
      VALUES($1, $2, $3, $4, $5, 'running', $6, $7, $8, $9, $10, $11, $12)
      ON CONFLICT (run_id) DO UPDATE SET
        outcome = 'running', ended_utc = NULL, resumes = runs.resumes + 1,
        pid = excluded.pid, host = excluded.host, software_version = excluded.software_version,
        operator = excluded.operator)sql";

const char* const kSqliteInsertAcceptance = R"sql(
        INSERT INTO acceptances(unit, run_id, passed, date_utc, recorded_utc, certificate_json, stand, host,
                                operator)
        VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?))sql";
const char* const kPostgresInsertAcceptance =
    "INSERT INTO acceptances(unit, run_id, passed, date_utc, recorded_utc, certificate_json, stand, "
    "host, operator) VALUES($1, $2, $3, $4, $5, $6, $7, $8, $9) RETURNING id";

const std::string kSqliteCalibrationParams =
    ":unit, :source, :run_id, :source_ref, :label, :date, :recorded, :method, :coefficients, :stand, :host, "
    ":operator, ";

template <typename T>
SqlValue or_null(const std::optional<T>& v) {
  if (v) return *v;
  return nullptr;
}

void add_stats(std::vector<SqlValue>& p, const std::optional<AxisResidualStats>& s) {
  const AxisResidualStats none;
  const AxisResidualStats& v = s ? *s : none;
  for (const auto& x : {v.mean_abs_arcsec, v.sd_arcsec, v.max_abs_arcsec, v.rms_arcsec}) p.push_back(or_null(x));
  p.push_back(or_null(v.points));
  p.push_back(or_null(v.range_lo_deg));
  p.push_back(or_null(v.range_hi_deg));
}

// Every row `sql` selects as a record, and the first (if any).
template <typename Record>
std::vector<Record> records(SqlSession& s, const std::string& sql, const std::vector<SqlValue>& p,
                            Record (*read)(const SqlRow&)) {
  std::vector<Record> out;
  s.select(sql, p, [&](const SqlRow& r) { out.push_back(read(r)); });
  return out;
}
template <typename Record>
std::optional<Record> first_record(SqlSession& s, const std::string& sql, const std::vector<SqlValue>& p,
                                   Record (*read)(const SqlRow&)) {
  std::vector<Record> all = records(s, sql, p, read);
  if (all.empty()) return std::nullopt;
  return std::move(all.front());
}

// The one text column of the first row `sql` selects; none when it selects nothing.
std::optional<std::string> first_text(SqlSession& s, const std::string& sql, const std::vector<SqlValue>& p,
                                      const std::string& column) {
  std::optional<std::string> out;
  s.select(sql, p, [&](const SqlRow& r) {
    if (!out) out = r.text(column);
  });
  return out;
}

bool insert_unit(SqlSession& s, Dialect d, const std::string& serial) {
  return s.exec(insert_if_new(d, "units(serial, first_seen_utc)", "serial", 2), {serial, utc_now_iso()}) == 1;
}

// True when `sql` selects a row.
bool selects_any(SqlSession& s, const std::string& sql, const std::vector<SqlValue>& p) {
  bool any = false;
  s.select(sql, p, [&](const SqlRow&) { any = true; });
  return any;
}

bool run_exists(SqlSession& s, Dialect d, const std::string& run_id) {
  return selects_any(s, "SELECT 1 FROM runs WHERE run_id = " + param(d, 1), {run_id});
}

// The insert itself, inside the caller's transaction.
int64_t insert_calibration(SqlSession& s, Dialect d, const CalibrationRecord& given) {
  if (given.run_id && !run_exists(s, d, *given.run_id)) {
    throw std::invalid_argument(fmt::format("record_calibration: no run {}", *given.run_id));
  }
  insert_unit(s, d, given.unit);
  const CalibrationRecord cal = as_recorded(given);
  std::vector<SqlValue> p{cal.unit,     cal.source,       or_null(cal.run_id), cal.source_ref,          cal.label,
                          cal.date_utc, cal.recorded_utc, cal.method,          cal.coefficients.dump(), cal.stand,
                          cal.host,     cal.operator_name};
  add_stats(p, cal.pitch);
  add_stats(p, cal.yaw);
  // SQLite's statement names its parameters, in the same order as the values.
  const std::string values = d == Dialect::sqlite ? kSqliteCalibrationParams + stat_columns(":{}_{}")
                                                  : params(d, static_cast<int>(p.size()));
  return s.insert(
      fmt::format("INSERT INTO calibrations(unit, source, run_id, source_ref, label, date_utc, recorded_utc, "
                  "method, coefficients_json, stand, host, operator, {}) VALUES({}){}",
                  stat_columns(), values, d == Dialect::sqlite ? "" : " RETURNING id"),
      p);
}

}  // namespace

bool SqlCatalogue::add_unit(const std::string& serial) {
  require_unit(serial);
  bool added = false;
  transact("add unit " + serial, [&](SqlSession& s) { added = insert_unit(s, dialect_, serial); });
  return added;
}

void SqlCatalogue::record_run_start(const RunStart& start) {
  check_run_start(start);
  transact("record the start of run " + start.run_id, [&](SqlSession& s) {
    const auto unit =
        first_text(s, "SELECT unit FROM runs WHERE run_id = " + param(dialect_, 1), {start.run_id}, "unit");
    if (unit && *unit != start.unit) {
      throw std::invalid_argument(fmt::format("run {} belongs to unit {}, not {}", start.run_id, *unit, start.unit));
    }
    // A run of several units is named by their serials joined with '+' (the runs' key into units):
    // each serial is a unit too, and units() lists only those.
    insert_unit(s, dialect_, start.unit);
    size_t from = 0;
    for (size_t plus = start.unit.find('+'); ; plus = start.unit.find('+', from)) {
      const std::string serial = start.unit.substr(from, plus == std::string::npos ? std::string::npos : plus - from);
      if (!serial.empty() && serial != start.unit) insert_unit(s, dialect_, serial);
      if (plus == std::string::npos) break;
      from = plus + 1;
    }
    const RunStart run = as_recorded(start);
    s.exec(dialect_ == Dialect::sqlite ? kSqliteStartRun : kPostgresStartRun,
           {run.run_id, run.unit, run.procedure, run.procedure_hash, run.started_utc, run.run_dir.string(),
            run.emulated, run.stand, run.software_version, static_cast<int64_t>(::getpid()), this_host(),
            run.operator_name});
  });
}

void SqlCatalogue::record_run_end(const std::string& run_id, RunOutcome outcome, const std::string& ended_utc) {
  transact("record the end of run " + run_id, [&](SqlSession& s) {
    const auto sql = fmt::format("UPDATE runs SET ended_utc = {}, outcome = {} WHERE run_id = {}", param(dialect_, 1),
                                 param(dialect_, 2), param(dialect_, 3));
    if (s.exec(sql, {ended_utc.empty() ? utc_now_iso() : ended_utc, std::string(to_string(outcome)), run_id}) != 1) {
      throw std::invalid_argument(fmt::format("record_run_end: no run {}", run_id));
    }
  });
}

int64_t SqlCatalogue::record_run_operator(const std::string& run_id, const std::string& operator_name) {
  int64_t changed = 0;
  transact("record the operator of run " + run_id, [&](SqlSession& s) {
    if (!run_exists(s, dialect_, run_id)) {
      throw std::invalid_argument(fmt::format("record_run_operator: no run {}", run_id));
    }
    const std::string p1 = param(dialect_, 1), p2 = param(dialect_, 2);
    changed = s.exec(fmt::format("UPDATE runs SET operator = {} WHERE run_id = {} AND operator <> {}", p1, p2,
                                 param(dialect_, 3)),
                     {operator_name, run_id, operator_name});
    // What the run recorded before its operator was known names none: it was the same operator's.
    for (const char* table : {"calibrations", "acceptances"}) {
      changed += s.exec(fmt::format("UPDATE {} SET operator = {} WHERE run_id = {} AND operator = ''", table, p1, p2),
                        {operator_name, run_id});
    }
  });
  return changed;
}

bool SqlCatalogue::copy_run(const RunRecord& r) {
  require_unit(r.unit);
  bool copied = false;
  transact("copy run " + r.run_id, [&](SqlSession& s) {
    insert_unit(s, dialect_, r.unit);
    const auto sql = insert_if_new(dialect_, fmt::format("runs({})", kRunColumns), "run_id", 15);
    copied = s.exec(sql, {r.run_id, r.unit, r.procedure, r.procedure_hash, r.started_utc, or_null(r.ended_utc),
                          r.outcome_name(), r.run_dir, r.emulated, r.stand, r.software_version, r.resumes, r.pid,
                          r.host, r.operator_name}) == 1;
  });
  return copied;
}

int64_t SqlCatalogue::record_calibration(const CalibrationRecord& cal) {
  check_calibration(cal);
  int64_t id = 0;
  transact("record a calibration of " + cal.unit, [&](SqlSession& s) { id = insert_calibration(s, dialect_, cal); });
  return id;
}

std::pair<int64_t, bool> SqlCatalogue::record_import_once(const CalibrationRecord& cal) {
  check_import(cal);
  std::pair<int64_t, bool> out;
  // One transaction makes check-then-insert safe: of two imports at once, SQLite's write lock makes
  // one wait; PostgreSQL's SERIALIZABLE redoes one, which then finds the other's.
  transact("import a calibration of " + cal.unit, [&](SqlSession& s) {
    const auto sql = fmt::format(
        "SELECT id FROM calibrations WHERE unit = {} AND source = 'import' AND date_utc = {} "
        "AND coefficients_json = {} ORDER BY id LIMIT 1",
        param(dialect_, 1), param(dialect_, 2), param(dialect_, 3));
    std::optional<int64_t> existing;
    s.select(sql, {cal.unit, cal.date_utc, cal.coefficients.dump()},
             [&](const SqlRow& r) { existing = r.integer("id"); });
    out = existing ? std::make_pair(*existing, false) : std::make_pair(insert_calibration(s, dialect_, cal), true);
  });
  return out;
}

int64_t SqlCatalogue::record_acceptance(const AcceptanceRecord& given) {
  require_unit(given.unit);
  int64_t id = 0;
  transact("record an acceptance of " + given.unit, [&](SqlSession& s) {
    if (given.run_id && !run_exists(s, dialect_, *given.run_id)) {
      throw std::invalid_argument(fmt::format("record_acceptance: no run {}", *given.run_id));
    }
    insert_unit(s, dialect_, given.unit);
    const AcceptanceRecord acc = as_recorded(given);
    id = s.insert(dialect_ == Dialect::sqlite ? kSqliteInsertAcceptance : kPostgresInsertAcceptance,
                  {acc.unit, or_null(acc.run_id), acc.passed, acc.date_utc, acc.recorded_utc, acc.certificate.dump(),
                   acc.stand, acc.host, acc.operator_name});
  });
  return id;
}

std::vector<std::string> SqlCatalogue::units() const {
  std::vector<std::string> out;
  query("list units", [&](SqlSession& s) {
    // Not the names of runs of several units (their serials joined by '+'; each serial is listed).
    s.select("SELECT serial FROM units WHERE serial NOT LIKE '%+%' ORDER BY serial", {},
             [&](const SqlRow& r) { out.push_back(r.text("serial")); });
  });
  return out;
}

bool SqlCatalogue::has_unit(const std::string& serial) const {
  bool found = false;
  query("look up unit " + serial, [&](SqlSession& s) {
    found = selects_any(s, "SELECT 1 FROM units WHERE serial = " + param(dialect_, 1), {serial});
  });
  return found;
}

std::vector<RunRecord> SqlCatalogue::list_runs(const RunFilter& filter) const {
  const bool sqlite = dialect_ == Dialect::sqlite;
  std::vector<SqlValue> p;
  std::string sql = fmt::format("SELECT {} FROM runs", kRunColumns);
  if (filter.unit) {
    p.push_back(*filter.unit);
    // A run of several units is named by their serials joined with '+': it is each unit's run too.
    const std::string u = sqlite ? std::string(":unit") : param(dialect_, 1);
    sql += fmt::format(" WHERE (unit = {0} OR {1}('+' || unit || '+', '+' || {0} || '+') > 0)", u, sqlite ? "instr" : "strpos");
  }
  // Equal start times: SQLite's entry order; PostgreSQL has no row order, so the run id decides.
  sql += sqlite ? " ORDER BY started_utc DESC, rowid DESC" : " ORDER BY started_utc DESC, run_id DESC";
  if (filter.limit) {
    p.push_back(static_cast<int64_t>(filter.limit));
    sql += " LIMIT " + (sqlite ? std::string(":limit") : param(dialect_, static_cast<int>(p.size())));
  }
  std::vector<RunRecord> out;
  query("list runs", [&](SqlSession& s) { out = records(s, sql, p, run_of_row<SqlRow>); });
  return out;
}

std::optional<RunRecord> SqlCatalogue::find_run(const std::string& run_id) const {
  std::optional<RunRecord> out;
  query("look up run " + run_id, [&](SqlSession& s) {
    const auto sql = fmt::format("SELECT {} FROM runs WHERE run_id = {}", kRunColumns, param(dialect_, 1));
    out = first_record(s, sql, {run_id}, run_of_row<SqlRow>);
  });
  return out;
}

std::vector<CalibrationRecord> SqlCatalogue::unit_history(const std::string& serial) const {
  std::vector<CalibrationRecord> out;
  query("read the history of " + serial, [&](SqlSession& s) {
    const auto sql = fmt::format("SELECT {} FROM calibrations WHERE unit = {} ORDER BY date_utc, id",
                                 calibration_columns(), param(dialect_, 1));
    out = records(s, sql, {serial}, calibration_of_row<SqlRow>);
  });
  return out;
}

std::optional<CalibrationRecord> SqlCatalogue::find_calibration(int64_t id) const {
  std::optional<CalibrationRecord> out;
  query(fmt::format("look up calibration {}", id), [&](SqlSession& s) {
    const auto sql =
        fmt::format("SELECT {} FROM calibrations WHERE id = {}", calibration_columns(), param(dialect_, 1));
    out = first_record(s, sql, {id}, calibration_of_row<SqlRow>);
  });
  return out;
}

std::vector<CalibrationRecord> SqlCatalogue::run_calibrations(const std::string& run_id) const {
  std::vector<CalibrationRecord> out;
  query("read the calibrations of run " + run_id, [&](SqlSession& s) {
    const auto sql = fmt::format("SELECT {} FROM calibrations WHERE run_id = {} ORDER BY id", calibration_columns(),
                                 param(dialect_, 1));
    out = records(s, sql, {run_id}, calibration_of_row<SqlRow>);
  });
  return out;
}

std::vector<AcceptanceRecord> SqlCatalogue::unit_acceptances(const std::string& serial) const {
  std::vector<AcceptanceRecord> out;
  query("read the acceptances of " + serial, [&](SqlSession& s) {
    const auto sql = fmt::format("SELECT {} FROM acceptances WHERE unit = {} ORDER BY date_utc, id", kAcceptanceColumns,
                                 param(dialect_, 1));
    out = records(s, sql, {serial}, acceptance_of_row<SqlRow>);
  });
  return out;
}

}  // namespace fpss
