// The PostgreSQL backend of the catalogue: one database a fleet of stands writes to at once (libpqxx).
#pragma once
#include <chrono>
#include <memory>
#include <string>

#include "stand/catalogue/sql_catalogue.h"

namespace fpss {

// How hard a PostgresCatalogue tries before it gives up and throws.
struct PostgresRetry {
  int max_attempts = 12;          // serialization failures (40001) and deadlocks (40P01)
  double reconnect_window_s = 5;  // a lost connection is reopened and the transaction redone this long
};

// Writes run in SERIALIZABLE transactions retried as a whole on 40001 and 40P01 (with a growing,
// jittered pause), so concurrent stands never lose or duplicate a record. A transaction whose
// commit is in doubt (the connection dropped during COMMIT) is not redone: it throws, and the run
// folder's pending mark makes the entry catch up idempotently (docs/fleet.md).
class PostgresCatalogue final : public SqlCatalogue {
 public:
  // Connects; read_write applies the migrations when the schema is older. Throws InputError for a
  // newer schema (or a read-only open of a database without one), std::runtime_error when the
  // server cannot be reached.
  explicit PostgresCatalogue(const std::string& url, Mode mode = Mode::read_write, PostgresRetry retry = {});
  ~PostgresCatalogue() override;
  PostgresCatalogue(const PostgresCatalogue&) = delete;
  PostgresCatalogue& operator=(const PostgresCatalogue&) = delete;

  std::string location() const override { return shown_url_; }
  std::string backend() const override { return "postgresql"; }

  std::string integrity_check() const override;
  int schema_version() const override;

  // How many transactions were redone (serialization failure, deadlock, lost connection): for tests.
  int64_t retries() const { return retries_; }

 private:
  struct Connection;  // the libpqxx connection, kept out of this header
  void transact(const std::string& what, const std::function<void(SqlSession&)>& body) override;
  void query(const std::string& what, const std::function<void(SqlSession&)>& body) const override;
  template <typename F>
  auto write(const std::string& what, F&& body);
  template <typename F>
  auto read(const std::string& what, F&& body) const;
  Connection& connection() const;
  // Within the reconnect window since `start`: counts a retry, pauses briefly, true; beyond: false.
  bool wait_to_reconnect(std::chrono::steady_clock::time_point start) const;
  void migrate();

  std::string url_, shown_url_;
  Mode mode_;
  PostgresRetry retry_;
  mutable std::unique_ptr<Connection> conn_;
  mutable int64_t retries_ = 0;
};

}  // namespace fpss
