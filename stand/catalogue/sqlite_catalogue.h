// The SQLite backend of the catalogue: one file per stand, the embedded default (RUNS_DIR/stand.db).
#pragma once
#include <filesystem>
#include <memory>

#include "stand/catalogue/catalogue.h"

namespace SQLite {
class Database;
}

namespace fpss {

// Safe for several processes at once (WAL, busy timeout, short IMMEDIATE transactions) and for a
// process killed at any point (SQLite's journal).
class SqliteCatalogue final : public Catalogue {
 public:
  // read_write creates the file (and its folder) and the schema when missing; read_only throws
  // InputError when the file is missing or not a catalogue. Both throw InputError for a schema
  // newer than this software knows.
  explicit SqliteCatalogue(const std::filesystem::path& path, Mode mode = Mode::read_write,
                           int busy_timeout_ms = 10000);
  ~SqliteCatalogue() override;
  SqliteCatalogue(const SqliteCatalogue&) = delete;
  SqliteCatalogue& operator=(const SqliteCatalogue&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::string location() const override { return path_.string(); }
  std::string backend() const override { return "sqlite"; }

  bool add_unit(const std::string& serial) override;
  void record_run_start(const RunStart& run) override;
  void record_run_end(const std::string& run_id, const std::string& outcome,
                      const std::string& ended_utc = "") override;
  bool copy_run(const RunRecord& run) override;
  int64_t record_calibration(const CalibrationRecord& cal) override;
  std::pair<int64_t, bool> record_import_once(const CalibrationRecord& cal) override;
  int64_t record_acceptance(const AcceptanceRecord& acc) override;

  std::vector<std::string> units() const override;
  bool has_unit(const std::string& serial) const override;
  std::vector<RunRecord> list_runs(const RunFilter& filter = {}) const override;
  std::optional<RunRecord> find_run(const std::string& run_id) const override;
  std::vector<CalibrationRecord> unit_history(const std::string& serial) const override;
  std::optional<CalibrationRecord> find_calibration(int64_t id) const override;
  std::vector<CalibrationRecord> run_calibrations(const std::string& run_id) const override;
  std::vector<AcceptanceRecord> unit_acceptances(const std::string& serial) const override;

  std::string integrity_check() const override;
  int schema_version() const override;

  // The connection, for tests; prefer the methods above.
  SQLite::Database& database() { return *db_; }

 private:
  void init_schema();
  std::filesystem::path path_;
  std::unique_ptr<SQLite::Database> db_;
};

}  // namespace fpss
