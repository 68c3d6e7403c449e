// The PostgreSQL backend: libpqxx, SERIALIZABLE writes retried on 40001/40P01, reconnection within a window.
#include "stand/catalogue/postgres_catalogue.h"

#include <fmt/format.h>
#include <unistd.h>

#include <pqxx/pqxx>

#include <chrono>
#include <random>
#include <regex>
#include <stdexcept>
#include <thread>
#include <type_traits>
#include <variant>

#include "base/errors.h"
#include "stand/catalogue/schema.h"

namespace fpss {
namespace {

using Clock = std::chrono::steady_clock;

// One row of a result, read by column name.
struct PgRow final : SqlRow {
  explicit PgRow(const pqxx::row& row) : r(row) {}
  const pqxx::row& r;

  std::string text(const std::string& c) const override { return r[c].as<std::string>(); }
  int64_t integer(const std::string& c) const override { return r[c].as<int64_t>(); }
  bool flag(const std::string& c) const override { return r[c].as<bool>(); }
  std::optional<std::string> opt_text(const std::string& c) const override {
    if (r[c].is_null()) return std::nullopt;
    return text(c);
  }
  std::optional<int64_t> opt_integer(const std::string& c) const override {
    if (r[c].is_null()) return std::nullopt;
    return integer(c);
  }
  std::optional<double> opt_real(const std::string& c) const override {
    if (r[c].is_null()) return std::nullopt;
    return r[c].as<double>();
  }
};

// Statements inside one libpqxx transaction. Parameters go as text, NULL where a value is absent
// (libpqxx 6 has no std::optional); the server converts them to the columns' types.
class PgSession final : public SqlSession {
 public:
  explicit PgSession(pqxx::transaction_base& w) : w_(w) {}

  int64_t exec(const std::string& sql, const std::vector<SqlValue>& params) override {
    return run(sql, params).affected_rows();
  }
  int64_t insert(const std::string& sql, const std::vector<SqlValue>& params) override {
    return run(sql, params)[0][0].as<int64_t>();
  }
  void select(const std::string& sql, const std::vector<SqlValue>& params,
              const std::function<void(const SqlRow&)>& each) override {
    for (const auto& r : run(sql, params)) each(PgRow(r));
  }

 private:
  static std::optional<std::string> as_text(const SqlValue& v) {
    return std::visit(
        [](const auto& x) -> std::optional<std::string> {
          using T = std::decay_t<decltype(x)>;
          if constexpr (std::is_same_v<T, std::nullptr_t>) return std::nullopt;
          else if constexpr (std::is_same_v<T, std::string>) return x;
          else if constexpr (std::is_same_v<T, bool>) return std::string(x ? "true" : "false");
          else if constexpr (std::is_same_v<T, double>) return fmt::format("{}", x);  // shortest round trip
          else return std::to_string(x);
        },
        v);
  }
  pqxx::result run(const std::string& sql, const std::vector<SqlValue>& params) {
    std::vector<std::optional<std::string>> texts;
    for (const auto& v : params) texts.push_back(as_text(v));
    std::vector<const char*> p;
    for (const auto& t : texts) p.push_back(t ? t->c_str() : nullptr);
    return w_.exec_params(sql, pqxx::prepare::make_dynamic_params(p));
  }

  pqxx::transaction_base& w_;
};

bool retryable(const pqxx::sql_error& e) { return e.sqlstate() == "40001" || e.sqlstate() == "40P01"; }

// A growing pause with jitter, so writers that collided do not collide again in step.
void back_off(int attempt) {
  thread_local std::minstd_rand rng(static_cast<unsigned>(::getpid()) ^
                                    static_cast<unsigned>(Clock::now().time_since_epoch().count()));
  const int cap_ms = std::min(200, 2 << std::min(attempt, 7));
  std::this_thread::sleep_for(std::chrono::milliseconds(1 + rng() % cap_ms));
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
    : SqlCatalogue(schema::Dialect::postgres),
      url_(with_connect_timeout(url)),
      shown_url_(url_for_messages(url)),
      mode_(mode),
      retry_(retry) {
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

void PostgresCatalogue::transact(const std::string& what, const std::function<void(SqlSession&)>& body) {
  write(what, [&](pqxx::transaction_base& w) {
    PgSession s(w);
    body(s);
    return 0;
  });
}

void PostgresCatalogue::query(const std::string& what, const std::function<void(SqlSession&)>& body) const {
  read(what, [&](pqxx::transaction_base& w) {
    PgSession s(w);
    body(s);
    return 0;
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
