// The PostgreSQL backend: libpqxx, SERIALIZABLE writes retried on 40001/40P01, reconnection within a window.
#include "stand/catalogue/postgres_catalogue.h"
#include "stand/catalogue/record_rules.h"

#include <fmt/format.h>
#include <unistd.h>

#include <pqxx/pqxx>

#include <chrono>
#include <random>
#include <regex>
#include <stdexcept>
#include <thread>

#include "calib/errors.h"
#include "procedures/recorder.h"
#include "stand/catalogue/schema.h"

namespace fpss {
namespace {

using Clock = std::chrono::steady_clock;

// Parameters of one statement, NULL where a value is absent (libpqxx 6 has no std::optional).
class Args {
 public:
  Args& s(const std::string& v) { v_.emplace_back(v); return *this; }
  Args& i(int64_t v) { v_.emplace_back(std::to_string(v)); return *this; }
  Args& b(bool v) { v_.emplace_back(v ? "true" : "false"); return *this; }
  Args& os(const std::optional<std::string>& v) { v_.push_back(v); return *this; }
  Args& od(const std::optional<double>& v) {
    v_.push_back(v ? std::optional<std::string>(fmt::format("{}", *v)) : std::nullopt);  // shortest round trip
    return *this;
  }
  Args& oi(const std::optional<int64_t>& v) {
    v_.push_back(v ? std::optional<std::string>(std::to_string(*v)) : std::nullopt);
    return *this;
  }
  pqxx::result exec(pqxx::transaction_base& w, const std::string& sql) const {
    std::vector<const char*> p;
    for (const auto& x : v_) p.push_back(x ? x->c_str() : nullptr);
    return w.exec_params(sql, pqxx::prepare::make_dynamic_params(p));
  }

 private:
  std::vector<std::optional<std::string>> v_;
};

void add_stats(Args& a, const std::optional<AxisResidualStats>& s) {
  const AxisResidualStats none;
  const AxisResidualStats& v = s ? *s : none;
  a.od(v.mean_abs_arcsec).od(v.sd_arcsec).od(v.max_abs_arcsec).od(v.rms_arcsec).oi(v.points);
  a.od(v.range_lo_deg).od(v.range_hi_deg);
}

// One row of a result, read by column name for the shared record readers (record_rules.h).
struct PgRow {
  const pqxx::row& r;

  std::string text(const std::string& c) const { return r[c].as<std::string>(); }
  int64_t integer(const std::string& c) const { return r[c].as<int64_t>(); }
  bool flag(const std::string& c) const { return r[c].as<bool>(); }
  std::optional<std::string> opt_text(const std::string& c) const {
    if (r[c].is_null()) return std::nullopt;
    return text(c);
  }
  std::optional<int64_t> opt_integer(const std::string& c) const {
    if (r[c].is_null()) return std::nullopt;
    return integer(c);
  }
  std::optional<double> opt_real(const std::string& c) const {
    if (r[c].is_null()) return std::nullopt;
    return r[c].as<double>();
  }
};

// Every row of a result as a record, in the result's order.
template <typename Record>
std::vector<Record> records_of(const pqxx::result& rows, Record (*read)(const PgRow&)) {
  std::vector<Record> out;
  out.reserve(rows.size());
  for (const auto& r : rows) out.push_back(read(PgRow{r}));
  return out;
}

// The first row of a result as a record; none when it is empty.
template <typename Record>
std::optional<Record> first_record(const pqxx::result& rows, Record (*read)(const PgRow&)) {
  if (rows.empty()) return std::nullopt;
  return read(PgRow{rows[0]});
}

bool insert_unit(pqxx::transaction_base& w, const std::string& serial) {
  return Args()
             .s(serial)
             .s(utc_now_iso())
             .exec(w, "INSERT INTO units(serial, first_seen_utc) VALUES($1, $2) ON CONFLICT (serial) DO NOTHING")
             .affected_rows() == 1;
}

bool run_exists(pqxx::transaction_base& w, const std::string& run_id) {
  return !Args().s(run_id).exec(w, "SELECT 1 FROM runs WHERE run_id = $1").empty();
}

bool retryable(const pqxx::sql_error& e) { return e.sqlstate() == "40001" || e.sqlstate() == "40P01"; }

// A growing pause with jitter, so writers that collided do not collide again in step.
void back_off(int attempt) {
  thread_local std::minstd_rand rng(static_cast<unsigned>(::getpid()) ^
                                    static_cast<unsigned>(Clock::now().time_since_epoch().count()));
  const int cap_ms = std::min(200, 2 << std::min(attempt, 7));
  std::this_thread::sleep_for(std::chrono::milliseconds(1 + rng() % cap_ms));
}

int64_t insert_calibration(pqxx::transaction_base& w, const CalibrationRecord& given) {
  if (given.run_id && !run_exists(w, *given.run_id)) {
    throw std::invalid_argument(fmt::format("record_calibration: no run {}", *given.run_id));
  }
  insert_unit(w, given.unit);
  const CalibrationRecord cal = as_recorded(given);
  Args a;
  a.s(cal.unit).s(cal.source).os(cal.run_id).s(cal.source_ref).s(cal.label);
  a.s(cal.date_utc).s(cal.recorded_utc).s(cal.method).s(cal.coefficients.dump());
  a.s(cal.stand).s(cal.host);
  add_stats(a, cal.pitch);
  add_stats(a, cal.yaw);
  std::string values;
  for (int k = 1; k <= 11 + 14; ++k) values += fmt::format("{}${}", k == 1 ? "" : ", ", k);
  return a
      .exec(w, fmt::format("INSERT INTO calibrations(unit, source, run_id, source_ref, label, date_utc, recorded_utc, "
                           "method, coefficients_json, stand, host, {}) VALUES({}) RETURNING id",
                           stat_columns(), values))[0][0]
      .as<int64_t>();
}

}  // namespace

std::string url_for_messages(const std::string& url) {
  static const std::regex pw(R"(^(\w+://[^:/@]*):[^@/]*@)");
  static const std::regex qpw(R"(([?&]password=)[^&]*)");
  return std::regex_replace(std::regex_replace(url, pw, "$1@"), qpw, "$1***");
}

struct PostgresCatalogue::Connection : pqxx::connection {
  using pqxx::connection::connection;
};

namespace {
// A server that does not answer (a host gone, a network cut) must not hold a run for TCP's own
// timeouts: libpq gives up connecting after connect_timeout unless the URL sets its own.
std::string with_connect_timeout(const std::string& url) {
  if (url.find("connect_timeout=") != std::string::npos) return url;
  return url + (url.find('?') == std::string::npos ? "?" : "&") + "connect_timeout=5";
}
}  // namespace

PostgresCatalogue::PostgresCatalogue(const std::string& url, Mode mode, PostgresRetry retry)
    : url_(with_connect_timeout(url)), shown_url_(url_for_messages(url)), mode_(mode), retry_(retry) {
  connection();
  // Migrations apply on first use, a read of an older schema included; only a writer creates one.
  const int before = schema_version();
  if (before < kSchemaVersion && (mode_ == Mode::read_write || before > 0)) migrate();
  const int v = schema_version();
  if (v == 0) throw InputError(fmt::format("{}: not a stand catalogue (no schema)", shown_url_));
  if (v > kSchemaVersion) {
    throw InputError(fmt::format("{}: catalogue schema version {} is newer than this fpss-stand ({})", shown_url_, v,
                                 kSchemaVersion));
  }
  if (v < kSchemaVersion) {
    throw InputError(fmt::format("{}: catalogue schema version {} but this fpss-stand reads version {} (a run with "
                                 "this version upgrades it)",
                                 shown_url_, v, kSchemaVersion));
  }
}

PostgresCatalogue::~PostgresCatalogue() = default;

PostgresCatalogue::Connection& PostgresCatalogue::connection() const {
  if (conn_ && conn_->is_open()) return *conn_;
  conn_.reset();
  try {
    conn_ = std::make_unique<Connection>(url_);
  } catch (const pqxx::broken_connection& e) {
    throw CatalogueUnavailable(fmt::format("{}: cannot connect: {}", shown_url_, e.what()));
  } catch (const pqxx::failure& e) {
    throw CatalogueUnavailable(fmt::format("{}: cannot connect: {}", shown_url_, e.what()));
  }
  return *conn_;
}

// Applies the missing migrations under a transaction-scoped advisory lock: stands opening a fresh
// database at once wait for the first and then find nothing to do. PostgreSQL's DDL is
// transactional, so a crash leaves the version before or after.
void PostgresCatalogue::migrate() {
  if (schema_version() == kSchemaVersion) return;  // the common case: no lock, no DDL privilege needed
  try {
    pqxx::work w(connection());
    w.exec("SELECT pg_advisory_xact_lock(7466511)");  // any fixed key: "the catalogue's schema"
    w.exec("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)");
    const auto r = w.exec("SELECT version FROM schema_version");
    const int v = r.empty() ? 0 : r[0][0].as<int>();
    if (v > kSchemaVersion) {
      throw InputError(fmt::format("{}: catalogue schema version {} is newer than this fpss-stand ({})", shown_url_,
                                   v, kSchemaVersion));
    }
    for (int step = v; step < kSchemaVersion; ++step) w.exec(schema::migration(step, schema::Dialect::postgres));
    if (r.empty()) w.exec(fmt::format("INSERT INTO schema_version(version) VALUES({})", kSchemaVersion));
    else w.exec(fmt::format("UPDATE schema_version SET version = {}", kSchemaVersion));
    w.commit();
  } catch (const pqxx::sql_error& e) {
    throw std::runtime_error(fmt::format("{}: cannot create or upgrade the schema: {}", shown_url_, e.what()));
  }
}

// One write: a SERIALIZABLE transaction redone on 40001/40P01 up to max_attempts, and on a lost
// connection (before COMMIT) within the reconnect window.
bool PostgresCatalogue::wait_to_reconnect(Clock::time_point start) const {
  if (std::chrono::duration<double>(Clock::now() - start).count() > retry_.reconnect_window_s) return false;
  ++retries_;
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  return true;
}

template <typename F>
auto PostgresCatalogue::write(const std::string& what, F&& body) {
  if (mode_ == Mode::read_only) throw std::logic_error(fmt::format("{}: {}: opened read-only", shown_url_, what));
  const auto start = Clock::now();
  for (int attempt = 1;; ++attempt) {
    try {
      pqxx::transaction<pqxx::serializable> w(connection());
      auto result = body(w);
      w.commit();
      return result;
    } catch (const pqxx::in_doubt_error& e) {
      conn_.reset();
      throw CatalogueUnavailable(fmt::format("{}: {}: the commit's outcome is unknown: {}", shown_url_, what, e.what()));
    } catch (const pqxx::broken_connection& e) {
      conn_.reset();
      if (!wait_to_reconnect(start)) {
        throw CatalogueUnavailable(fmt::format("{}: {}: connection lost: {}", shown_url_, what, e.what()));
      }
    } catch (const pqxx::transaction_rollback& e) {
      // libpqxx 6 files 40001 (serialization_failure) and 40P01 (deadlock_detected) here, not
      // under sql_error; both mean "redo the whole transaction".
      if (attempt >= retry_.max_attempts) {
        throw std::runtime_error(fmt::format("{}: {}: still conflicting after {} attempts: {}", shown_url_, what,
                                             attempt, e.what()));
      }
      ++retries_;
      back_off(attempt);
    } catch (const pqxx::sql_error& e) {
      if (!retryable(e) || attempt >= retry_.max_attempts) {
        throw std::runtime_error(fmt::format("{}: {}: {}", shown_url_, what, e.what()));
      }
      ++retries_;
      back_off(attempt);
    } catch (const CatalogueUnavailable&) {
      // connection() failed while the server is away: the same window as a lost connection
      if (!wait_to_reconnect(start)) throw;
    }
  }
}

template <typename F>
auto PostgresCatalogue::read(const std::string& what, F&& body) const {
  const auto start = Clock::now();
  for (;;) {
    try {
      pqxx::read_transaction w(connection());
      return body(w);
    } catch (const pqxx::broken_connection& e) {
      conn_.reset();
      if (!wait_to_reconnect(start)) {
        throw CatalogueUnavailable(fmt::format("{}: {}: connection lost: {}", shown_url_, what, e.what()));
      }
    } catch (const CatalogueUnavailable&) {
      if (!wait_to_reconnect(start)) throw;
    } catch (const pqxx::sql_error& e) {
      throw std::runtime_error(fmt::format("{}: cannot {}: {}", shown_url_, what, e.what()));
    }
  }
}

int PostgresCatalogue::schema_version() const {
  return read("read the schema version", [&](pqxx::transaction_base& w) {
    if (w.exec("SELECT to_regclass('schema_version') IS NOT NULL")[0][0].as<bool>() == false) return 0;
    const auto r = w.exec("SELECT version FROM schema_version");
    return r.empty() ? 0 : r[0][0].as<int>();
  });
}

bool PostgresCatalogue::add_unit(const std::string& serial) {
  require_unit(serial);
  return write("add unit " + serial, [&](pqxx::transaction_base& w) { return insert_unit(w, serial); });
}

void PostgresCatalogue::record_run_start(const RunStart& start) {
  check_run_start(start);
  write("record the start of run " + start.run_id, [&](pqxx::transaction_base& w) {
    const auto q = Args().s(start.run_id).exec(w, "SELECT unit FROM runs WHERE run_id = $1");
    if (!q.empty() && q[0][0].as<std::string>() != start.unit) {
      throw std::invalid_argument(
          fmt::format("run {} belongs to unit {}, not {}", start.run_id, q[0][0].as<std::string>(), start.unit));
    }
    insert_unit(w, start.unit);
    const RunStart run = as_recorded(start);
    Args a;
    a.s(run.run_id).s(run.unit).s(run.procedure).s(run.procedure_hash).s(run.started_utc).s(run.run_dir.string());
    a.b(run.emulated).s(run.stand).s(run.software_version).i(::getpid()).s(this_host());
    a.exec(w, R"sql(
      INSERT INTO runs(run_id, unit, procedure, procedure_hash, started_utc, outcome, run_dir,
                       emulated, stand, software_version, pid, host)
      VALUES($1, $2, $3, $4, $5, 'running', $6, $7, $8, $9, $10, $11)
      ON CONFLICT (run_id) DO UPDATE SET
        outcome = 'running', ended_utc = NULL, resumes = runs.resumes + 1,
        pid = excluded.pid, host = excluded.host, software_version = excluded.software_version)sql");
    return 0;
  });
}

void PostgresCatalogue::record_run_end(const std::string& run_id, const std::string& outcome,
                                       const std::string& ended_utc) {
  check_run_end(outcome);
  write("record the end of run " + run_id, [&](pqxx::transaction_base& w) {
    const auto r = Args()
                       .s(ended_utc.empty() ? utc_now_iso() : ended_utc)
                       .s(outcome)
                       .s(run_id)
                       .exec(w, "UPDATE runs SET ended_utc = $1, outcome = $2 WHERE run_id = $3");
    if (r.affected_rows() != 1) throw std::invalid_argument(fmt::format("record_run_end: no run {}", run_id));
    return 0;
  });
}

bool PostgresCatalogue::copy_run(const RunRecord& x) {
  require_unit(x.unit);
  return write("copy run " + x.run_id, [&](pqxx::transaction_base& w) {
    insert_unit(w, x.unit);
    Args a;
    a.s(x.run_id).s(x.unit).s(x.procedure).s(x.procedure_hash).s(x.started_utc).os(x.ended_utc).s(x.outcome);
    a.s(x.run_dir).b(x.emulated).s(x.stand).s(x.software_version).i(x.resumes).i(x.pid).s(x.host);
    return a.exec(w, fmt::format("INSERT INTO runs({}) VALUES($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, "
                                 "$13, $14) ON CONFLICT (run_id) DO NOTHING",
                                 kRunColumns))
               .affected_rows() == 1;
  });
}

int64_t PostgresCatalogue::record_calibration(const CalibrationRecord& cal) {
  check_calibration(cal);
  return write("record a calibration of " + cal.unit,
               [&](pqxx::transaction_base& w) { return insert_calibration(w, cal); });
}

std::pair<int64_t, bool> PostgresCatalogue::record_import_once(const CalibrationRecord& cal) {
  check_import(cal);
  // SERIALIZABLE makes check-then-insert safe: of two imports at once, one is redone and finds the other's.
  return write("import a calibration of " + cal.unit, [&](pqxx::transaction_base& w) -> std::pair<int64_t, bool> {
    const auto q = Args().s(cal.unit).s(cal.date_utc).s(cal.coefficients.dump()).exec(
        w, "SELECT id FROM calibrations WHERE unit = $1 AND source = 'import' AND date_utc = $2 "
           "AND coefficients_json = $3 ORDER BY id LIMIT 1");
    if (!q.empty()) return {q[0][0].as<int64_t>(), false};
    return {insert_calibration(w, cal), true};
  });
}

int64_t PostgresCatalogue::record_acceptance(const AcceptanceRecord& given) {
  require_unit(given.unit);
  return write("record an acceptance of " + given.unit, [&](pqxx::transaction_base& w) {
    if (given.run_id && !run_exists(w, *given.run_id)) {
      throw std::invalid_argument(fmt::format("record_acceptance: no run {}", *given.run_id));
    }
    insert_unit(w, given.unit);
    const AcceptanceRecord acc = as_recorded(given);
    return Args()
        .s(acc.unit)
        .os(acc.run_id)
        .b(acc.passed)
        .s(acc.date_utc)
        .s(acc.recorded_utc)
        .s(acc.certificate.dump())
        .s(acc.stand)
        .s(acc.host)
        .exec(w, "INSERT INTO acceptances(unit, run_id, passed, date_utc, recorded_utc, certificate_json, stand, "
                 "host) VALUES($1, $2, $3, $4, $5, $6, $7, $8) RETURNING id")[0][0]
        .as<int64_t>();
  });
}

std::vector<std::string> PostgresCatalogue::units() const {
  return read("list units", [&](pqxx::transaction_base& w) {
    std::vector<std::string> out;
    for (const auto& r : w.exec("SELECT serial FROM units ORDER BY serial")) out.push_back(r[0].as<std::string>());
    return out;
  });
}

bool PostgresCatalogue::has_unit(const std::string& serial) const {
  return read("look up unit " + serial, [&](pqxx::transaction_base& w) {
    return !Args().s(serial).exec(w, "SELECT 1 FROM units WHERE serial = $1").empty();
  });
}

std::vector<RunRecord> PostgresCatalogue::list_runs(const RunFilter& filter) const {
  return read("list runs", [&](pqxx::transaction_base& w) {
    Args a;
    std::string sql = fmt::format("SELECT {} FROM runs", kRunColumns);
    if (filter.unit) {
      a.s(*filter.unit);
      sql += " WHERE unit = $1";
    }
    sql += " ORDER BY started_utc DESC, run_id DESC";
    if (filter.limit) {
      a.i(static_cast<int64_t>(filter.limit));
      sql += fmt::format(" LIMIT ${}", filter.unit ? 2 : 1);
    }
    return records_of(a.exec(w, sql), run_of_row<PgRow>);
  });
}

std::optional<RunRecord> PostgresCatalogue::find_run(const std::string& run_id) const {
  return read("look up run " + run_id, [&](pqxx::transaction_base& w) {
    const auto sql = fmt::format("SELECT {} FROM runs WHERE run_id = $1", kRunColumns);
    return first_record(Args().s(run_id).exec(w, sql), run_of_row<PgRow>);
  });
}

std::vector<CalibrationRecord> PostgresCatalogue::unit_history(const std::string& serial) const {
  return read("read the history of " + serial, [&](pqxx::transaction_base& w) {
    const auto sql =
        fmt::format("SELECT {} FROM calibrations WHERE unit = $1 ORDER BY date_utc, id", calibration_columns());
    return records_of(Args().s(serial).exec(w, sql), calibration_of_row<PgRow>);
  });
}

std::optional<CalibrationRecord> PostgresCatalogue::find_calibration(int64_t id) const {
  return read(fmt::format("look up calibration {}", id), [&](pqxx::transaction_base& w) {
    const auto sql = fmt::format("SELECT {} FROM calibrations WHERE id = $1", calibration_columns());
    return first_record(Args().i(id).exec(w, sql), calibration_of_row<PgRow>);
  });
}

std::vector<CalibrationRecord> PostgresCatalogue::run_calibrations(const std::string& run_id) const {
  return read("read the calibrations of run " + run_id, [&](pqxx::transaction_base& w) {
    const auto sql = fmt::format("SELECT {} FROM calibrations WHERE run_id = $1 ORDER BY id", calibration_columns());
    return records_of(Args().s(run_id).exec(w, sql), calibration_of_row<PgRow>);
  });
}

std::vector<AcceptanceRecord> PostgresCatalogue::unit_acceptances(const std::string& serial) const {
  return read("read the acceptances of " + serial, [&](pqxx::transaction_base& w) {
    const auto sql = fmt::format("SELECT {} FROM acceptances WHERE unit = $1 ORDER BY date_utc, id", kAcceptanceColumns);
    return records_of(Args().s(serial).exec(w, sql), acceptance_of_row<PgRow>);
  });
}

std::string PostgresCatalogue::integrity_check() const {
  try {
    return read("check", [&](pqxx::transaction_base& w) {
      return w.exec("SELECT 1")[0][0].as<int>() == 1 ? std::string("ok") : std::string("no answer");
    });
  } catch (const std::exception& e) {
    return fmt::format("integrity_check failed: {}", e.what());
  }
}

}  // namespace fpss
