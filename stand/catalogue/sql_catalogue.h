// The catalogue's operations written once for both SQL backends, over a small primitive each backend gives.
#pragma once
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "stand/catalogue/catalogue.h"
#include "stand/catalogue/schema.h"

namespace fpss {

// A statement's parameter: NULL, text, an integer, a real or a boolean. Never build one from a
// string literal: a `const char*` would become the boolean.
using SqlValue = std::variant<std::nullptr_t, std::string, int64_t, double, bool>;

// One row of a result, read by column name, as the record readers of record_rules.h take it.
class SqlRow {
 public:
  virtual ~SqlRow() = default;
  virtual std::string text(const std::string& c) const = 0;
  virtual int64_t integer(const std::string& c) const = 0;
  virtual bool flag(const std::string& c) const = 0;
  virtual std::optional<std::string> opt_text(const std::string& c) const = 0;
  virtual std::optional<int64_t> opt_integer(const std::string& c) const = 0;
  virtual std::optional<double> opt_real(const std::string& c) const = 0;
};

// The statements of one read or write, in the backend's connection. Parameters are positional, in
// the order they stand in the SQL text (SQLite numbers its named parameters the same way).
class SqlSession {
 public:
  virtual ~SqlSession() = default;
  // Returns how many rows the statement changed.
  virtual int64_t exec(const std::string& sql, const std::vector<SqlValue>& params) = 0;
  // An INSERT of one row; returns its id (PostgreSQL's statement says RETURNING id).
  virtual int64_t insert(const std::string& sql, const std::vector<SqlValue>& params) = 0;
  // Calls `each` for every row of the result, in order.
  virtual void select(const std::string& sql, const std::vector<SqlValue>& params,
                      const std::function<void(const SqlRow&)>& each) = 0;
};

// Both backends keep the same records by the same rules; they differ in how a statement is spelled
// (the dialect), and in how a transaction is held, retried and reported (transact and query).
class SqlCatalogue : public Catalogue {
 public:
  bool add_unit(const std::string& serial) final;
  void record_run_start(const RunStart& run) final;
  void record_run_end(const std::string& run_id, RunOutcome outcome, const std::string& ended_utc = "") final;
  int64_t record_run_operator(const std::string& run_id, const std::string& operator_name) final;
  bool copy_run(const RunRecord& run) final;
  int64_t record_calibration(const CalibrationRecord& cal) final;
  std::pair<int64_t, bool> record_import_once(const CalibrationRecord& cal) final;
  int64_t record_acceptance(const AcceptanceRecord& acc) final;

  std::vector<std::string> units() const final;
  bool has_unit(const std::string& serial) const final;
  std::vector<RunRecord> list_runs(const RunFilter& filter = {}) const final;
  std::optional<RunRecord> find_run(const std::string& run_id) const final;
  std::vector<CalibrationRecord> unit_history(const std::string& serial) const final;
  std::optional<CalibrationRecord> find_calibration(int64_t id) const final;
  std::vector<CalibrationRecord> run_calibrations(const std::string& run_id) const final;
  std::vector<AcceptanceRecord> unit_acceptances(const std::string& serial) const final;

 protected:
  explicit SqlCatalogue(schema::Dialect dialect) : dialect_(dialect) {}

  // Runs `body` as one write transaction, done again as a whole where the backend retries.
  // `what` ("add unit X") names it in the backend's error messages.
  virtual void transact(const std::string& what, const std::function<void(SqlSession&)>& body) = 0;
  // Runs `body`, which only reads.
  virtual void query(const std::string& what, const std::function<void(SqlSession&)>& body) const = 0;

 private:
  schema::Dialect dialect_;
};

}  // namespace fpss
