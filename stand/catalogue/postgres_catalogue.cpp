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
#include "stand/catalogue/postgres_schema.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

static_assert(std::size(postgres_schema::kMigrations) == Catalogue::kSchemaVersion);

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

std::optional<std::string> opt_text(const pqxx::field& f) {
  if (f.is_null()) return std::nullopt;
  return f.as<std::string>();
}
std::optional<double> opt_double(const pqxx::field& f) {
  if (f.is_null()) return std::nullopt;
  return f.as<double>();
}

std::string stat_columns() {
  std::string out;
  for (const char* axis : {"pitch", "yaw"}) {
    for (const char* k : kStatColumns) out += fmt::format("{}{}_{}", out.empty() ? "" : ", ", axis, k);
  }
  return out;
}

void add_stats(Args& a, const std::optional<AxisResidualStats>& s) {
  const AxisResidualStats none;
  const AxisResidualStats& v = s ? *s : none;
  a.od(v.mean_abs_arcsec).od(v.sd_arcsec).od(v.max_abs_arcsec).od(v.rms_arcsec).oi(v.points);
  a.od(v.range_lo_deg).od(v.range_hi_deg);
}

std::optional<AxisResidualStats> read_stats(const pqxx::row& r, const std::string& axis) {
  auto col = [&](const char* k) { return r[axis + "_" + k]; };
  AxisResidualStats s;
  s.mean_abs_arcsec = opt_double(col("mean_abs_arcsec"));
  s.sd_arcsec = opt_double(col("sd_arcsec"));
  s.max_abs_arcsec = opt_double(col("max_abs_arcsec"));
  s.rms_arcsec = opt_double(col("rms_arcsec"));
  if (!col("points").is_null()) s.points = col("points").as<int64_t>();
  s.range_lo_deg = opt_double(col("range_lo_deg"));
  s.range_hi_deg = opt_double(col("range_hi_deg"));
  if (s.empty()) return std::nullopt;
  return s;
}

const char* const kRunColumns =
    "run_id, unit, procedure, procedure_hash, started_utc, ended_utc, outcome, run_dir, emulated, "
    "stand, software_version, resumes, pid, host";

RunRecord read_run(const pqxx::row& r) {
  RunRecord x;
  x.run_id = r["run_id"].as<std::string>();
  x.unit = r["unit"].as<std::string>();
  x.procedure = r["procedure"].as<std::string>();
  x.procedure_hash = r["procedure_hash"].as<std::string>();
  x.started_utc = r["started_utc"].as<std::string>();
  x.ended_utc = opt_text(r["ended_utc"]);
  x.outcome = r["outcome"].as<std::string>();
  x.run_dir = r["run_dir"].as<std::string>();
  x.emulated = r["emulated"].as<bool>();
  x.stand = r["stand"].as<std::string>();
  x.software_version = r["software_version"].as<std::string>();
  x.resumes = r["resumes"].as<int64_t>();
  x.pid = r["pid"].as<int64_t>();
  x.host = r["host"].as<std::string>();
  return x;
}

const std::string kCalibrationColumns =
    "id, unit, source, run_id, source_ref, label, date_utc, recorded_utc, method, coefficients_json, stand, host, " +
    stat_columns();

CalibrationRecord read_calibration(const pqxx::row& r) {
  CalibrationRecord c;
  c.id = r["id"].as<int64_t>();
  c.unit = r["unit"].as<std::string>();
  c.source = r["source"].as<std::string>();
  c.run_id = opt_text(r["run_id"]);
  c.source_ref = r["source_ref"].as<std::string>();
  c.label = r["label"].as<std::string>();
  c.date_utc = r["date_utc"].as<std::string>();
  c.recorded_utc = r["recorded_utc"].as<std::string>();
  c.method = r["method"].as<std::string>();
  c.coefficients = nlohmann::json::parse(r["coefficients_json"].as<std::string>());
  c.stand = r["stand"].as<std::string>();
  c.host = r["host"].as<std::string>();
  c.pitch = read_stats(r, "pitch");
  c.yaw = read_stats(r, "yaw");
  return c;
}

const char* const kAcceptanceColumns =
    "id, unit, run_id, passed, date_utc, recorded_utc, certificate_json, stand, host";

AcceptanceRecord read_acceptance(const pqxx::row& r) {
  AcceptanceRecord a;
  a.id = r["id"].as<int64_t>();
  a.unit = r["unit"].as<std::string>();
  a.run_id = opt_text(r["run_id"]);
  a.passed = r["passed"].as<bool>();
  a.date_utc = r["date_utc"].as<std::string>();
  a.recorded_utc = r["recorded_utc"].as<std::string>();
  a.certificate = nlohmann::json::parse(r["certificate_json"].as<std::string>());
  a.stand = r["stand"].as<std::string>();
  a.host = r["host"].as<std::string>();
  return a;
}

// Every row of a result as a record, in the result's order.
template <typename Record>
std::vector<Record> records_of(const pqxx::result& rows, Record (*read)(const pqxx::row&)) {
  std::vector<Record> out;
  out.reserve(rows.size());
  for (const auto& r : rows) out.push_back(read(r));
  return out;
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

int64_t insert_calibration(pqxx::transaction_base& w, const CalibrationRecord& cal) {
  if (cal.run_id && !run_exists(w, *cal.run_id)) {
    throw std::invalid_argument(fmt::format("record_calibration: no run {}", *cal.run_id));
  }
  insert_unit(w, cal.unit);
  const std::string now = utc_now_iso();
  Args a;
  a.s(cal.unit).s(cal.source).os(cal.run_id);
  a.s(cal.source_ref.empty() && cal.run_id ? *cal.run_id : cal.source_ref).s(cal.label);
  a.s(cal.date_utc.empty() ? now : cal.date_utc).s(now).s(cal.method).s(cal.coefficients.dump());
  a.s(cal.stand).s(cal.host.empty() ? this_host() : cal.host);
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
// database at once wait for the first and then find nothing to do.
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
    for (int step = v; step < kSchemaVersion; ++step) w.exec(postgres_schema::kMigrations[step]);
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

void PostgresCatalogue::record_run_start(const RunStart& run) {
  if (run.run_id.empty()) throw std::invalid_argument("record_run_start: empty run id");
  require_unit(run.unit);
  write("record the start of run " + run.run_id, [&](pqxx::transaction_base& w) {
    const auto q = Args().s(run.run_id).exec(w, "SELECT unit FROM runs WHERE run_id = $1");
    if (!q.empty() && q[0][0].as<std::string>() != run.unit) {
      throw std::invalid_argument(
          fmt::format("run {} belongs to unit {}, not {}", run.run_id, q[0][0].as<std::string>(), run.unit));
    }
    insert_unit(w, run.unit);
    Args a;
    a.s(run.run_id).s(run.unit).s(run.procedure).s(run.procedure_hash);
    a.s(run.started_utc.empty() ? utc_now_iso() : run.started_utc);
    a.s(run.run_dir.empty() ? std::string() : fs::absolute(run.run_dir).lexically_normal().string());
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
  if (outcome.empty() || outcome == outcome::running) {
    throw std::invalid_argument("record_run_end: the outcome must be a final one");
  }
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
  check_calibration(cal);
  if (cal.source != "import") throw std::invalid_argument("record_import_once: the calibration is not an import");
  if (cal.date_utc.empty()) throw std::invalid_argument("record_import_once: an import needs its date");
  // SERIALIZABLE makes check-then-insert safe: of two imports at once, one is redone and finds the other's.
  return write("import a calibration of " + cal.unit, [&](pqxx::transaction_base& w) -> std::pair<int64_t, bool> {
    const auto q = Args().s(cal.unit).s(cal.date_utc).s(cal.coefficients.dump()).exec(
        w, "SELECT id FROM calibrations WHERE unit = $1 AND source = 'import' AND date_utc = $2 "
           "AND coefficients_json = $3 ORDER BY id LIMIT 1");
    if (!q.empty()) return {q[0][0].as<int64_t>(), false};
    return {insert_calibration(w, cal), true};
  });
}

int64_t PostgresCatalogue::record_acceptance(const AcceptanceRecord& acc) {
  require_unit(acc.unit);
  return write("record an acceptance of " + acc.unit, [&](pqxx::transaction_base& w) {
    if (acc.run_id && !run_exists(w, *acc.run_id)) {
      throw std::invalid_argument(fmt::format("record_acceptance: no run {}", *acc.run_id));
    }
    insert_unit(w, acc.unit);
    const std::string now = utc_now_iso();
    return Args()
        .s(acc.unit)
        .os(acc.run_id)
        .b(acc.passed)
        .s(acc.date_utc.empty() ? now : acc.date_utc)
        .s(now)
        .s(acc.certificate.dump())
        .s(acc.stand)
        .s(acc.host.empty() ? this_host() : acc.host)
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
    return records_of(a.exec(w, sql), read_run);
  });
}

std::optional<RunRecord> PostgresCatalogue::find_run(const std::string& run_id) const {
  return read("look up run " + run_id, [&](pqxx::transaction_base& w) -> std::optional<RunRecord> {
    const auto r = Args().s(run_id).exec(w, fmt::format("SELECT {} FROM runs WHERE run_id = $1", kRunColumns));
    if (r.empty()) return std::nullopt;
    return read_run(r[0]);
  });
}

std::vector<CalibrationRecord> PostgresCatalogue::unit_history(const std::string& serial) const {
  return read("read the history of " + serial, [&](pqxx::transaction_base& w) {
    return records_of(Args().s(serial).exec(w, fmt::format(
                          "SELECT {} FROM calibrations WHERE unit = $1 ORDER BY date_utc, id", kCalibrationColumns)),
                      read_calibration);
  });
}

std::optional<CalibrationRecord> PostgresCatalogue::find_calibration(int64_t id) const {
  return read(fmt::format("look up calibration {}", id), [&](pqxx::transaction_base& w) -> std::optional<CalibrationRecord> {
    const auto r = Args().i(id).exec(w, fmt::format("SELECT {} FROM calibrations WHERE id = $1", kCalibrationColumns));
    if (r.empty()) return std::nullopt;
    return read_calibration(r[0]);
  });
}

std::vector<CalibrationRecord> PostgresCatalogue::run_calibrations(const std::string& run_id) const {
  return read("read the calibrations of run " + run_id, [&](pqxx::transaction_base& w) {
    return records_of(Args().s(run_id).exec(
                          w, fmt::format("SELECT {} FROM calibrations WHERE run_id = $1 ORDER BY id", kCalibrationColumns)),
                      read_calibration);
  });
}

std::vector<AcceptanceRecord> PostgresCatalogue::unit_acceptances(const std::string& serial) const {
  return read("read the acceptances of " + serial, [&](pqxx::transaction_base& w) {
    return records_of(Args().s(serial).exec(w, fmt::format(
                          "SELECT {} FROM acceptances WHERE unit = $1 ORDER BY date_utc, id", kAcceptanceColumns)),
                      read_acceptance);
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
