// The stand's catalogue of units, runs, calibrations and acceptances: one SQLite file shared by runs.
#pragma once
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace SQLite {
class Database;
}

namespace fpss {

// Table 1 of the paper for one axis, as the calibrator writes `residuals.<axis>` in
// calibration.json. Each figure is optional: the paper's Table 1 leaves some unprinted, and
// imported calibrations may carry none.
struct AxisResidualStats {
  std::optional<double> mean_abs_arcsec;  // mean |residual|
  std::optional<double> sd_arcsec;        // standard deviation of |residual|
  std::optional<double> max_abs_arcsec;
  std::optional<double> rms_arcsec;
  std::optional<int64_t> points;
  std::optional<double> range_lo_deg, range_hi_deg;  // reference angles the points span

  bool empty() const;
  // From {"mean_abs_arcsec", "sd_arcsec", "max_abs_arcsec", "rms_arcsec", "points",
  // "range_deg": [lo, hi]}, any of them absent or null; throws InputError naming `where` and
  // the key for a wrong type.
  static AxisResidualStats from_json(const nlohmann::json& j, const std::string& where);
  nlohmann::json to_json() const;  // the same shape, absent figures left out
};

// What the engine knows when a run starts. The run id is the run folder's name.
struct RunStart {
  std::string run_id;
  std::string unit;                // sensor serial
  std::string procedure;           // procedure name (file stem)
  std::string procedure_hash;      // hash of the procedure text, as run.json holds it
  std::string started_utc;         // ISO 8601, e.g. 2024-05-01T12:00:00Z; empty: now
  std::filesystem::path run_dir;   // stored absolute
  bool emulated = false;
  std::string stand;               // stand identity (stand file or name); "" when emulated
  std::string software_version = FPSS_VERSION;
};

// Outcomes the engine records; `running` until record_run_end.
namespace outcome {
inline constexpr const char* running = "running";
inline constexpr const char* completed = "completed";
inline constexpr const char* interrupted = "interrupted";
inline constexpr const char* failed = "failed";
}  // namespace outcome

struct RunRecord {
  std::string run_id;
  std::string unit;
  std::string procedure;
  std::string procedure_hash;
  std::string started_utc;
  std::optional<std::string> ended_utc;
  std::string outcome;
  std::string run_dir;
  bool emulated = false;
  std::string stand;
  std::string software_version;
  int64_t resumes = 0;  // how many times the run was resumed
  int64_t pid = 0;      // process that last started or resumed it
  std::string host;     // and its host name
  // True when the run says `running` but its process is gone from this host (killed run).
  bool stale() const;
};

// A calibration of a unit, from a run on this stand or imported from elsewhere.
struct CalibrationRecord {
  int64_t id = 0;                      // assigned by record_calibration
  std::string unit;
  std::string source = "run";          // "run" or "import"
  std::optional<std::string> run_id;   // set when source == "run"
  std::string source_ref;              // the run id, or the imported file's path
  std::string label;                   // free name, e.g. the paper's "VI"; may be empty
  std::string date_utc;                // when the calibration was made (ISO 8601 date or time)
  std::string recorded_utc;            // when it entered the catalogue (set by the catalogue)
  std::string method;                  // "differences", "absolute", "imported", ...
  nlohmann::json coefficients;         // the coefficient file's JSON, as written or imported
  std::optional<AxisResidualStats> pitch, yaw;

  // Fills coefficients, method and the residual stats from a calibration.json's content.
  static CalibrationRecord from_calibration_json(const nlohmann::json& cal, const std::string& origin);
};

// An acceptance verdict with its certificate (accept writes the certificate).
struct AcceptanceRecord {
  int64_t id = 0;
  std::string unit;
  std::optional<std::string> run_id;
  bool passed = false;
  std::string date_utc;
  std::string recorded_utc;
  nlohmann::json certificate = nlohmann::json::object();  // acceptance.json's content
};

struct RunFilter {
  std::optional<std::string> unit;
  size_t limit = 0;  // 0: all; otherwise the most recent `limit`
};

// Owns one connection. Safe for several processes at once (WAL, busy timeout, short IMMEDIATE
// transactions) and for a process killed at any point (SQLite's journal). Not for sharing one
// object between threads: give each thread its own Catalogue.
class Catalogue {
 public:
  enum class Mode { read_write, read_only };
  static constexpr int kSchemaVersion = 1;

  // read_write creates the file (and its folder) and the schema when missing; read_only throws
  // InputError when the file is missing or not a catalogue. Both throw InputError for a schema
  // newer than this software knows.
  explicit Catalogue(const std::filesystem::path& path, Mode mode = Mode::read_write,
                     int busy_timeout_ms = 10000);
  ~Catalogue();
  Catalogue(const Catalogue&) = delete;
  Catalogue& operator=(const Catalogue&) = delete;

  // `runs/stand.db` under a runs folder: the default catalogue of `--runs-dir`.
  static std::filesystem::path default_path(const std::filesystem::path& runs_dir = "runs");

  const std::filesystem::path& path() const { return path_; }

  // Registers the unit if new. Returns true when it was new.
  bool add_unit(const std::string& serial);

  // Inserts the run as `running`. Starting an existing run id again (a resume) keeps its
  // start time, sets it back to `running`, clears its end and counts the resume.
  void record_run_start(const RunStart& run);
  // Sets the end time (empty: now) and outcome. Throws std::invalid_argument for an unknown run.
  void record_run_end(const std::string& run_id, const std::string& outcome,
                      const std::string& ended_utc = "");
  // Returns the new calibration's id. Registers the unit; checks run_id exists when given.
  int64_t record_calibration(const CalibrationRecord& cal);
  // An import (source "import") recorded unless the unit already holds an import of the same date
  // with the same coefficient JSON; check and insert are one transaction, so two processes
  // importing one file at once record it once. Returns the id and whether it was new.
  std::pair<int64_t, bool> record_import_once(const CalibrationRecord& cal);
  int64_t record_acceptance(const AcceptanceRecord& acc);

  std::vector<std::string> units() const;
  bool has_unit(const std::string& serial) const;
  // Most recent first.
  std::vector<RunRecord> list_runs(const RunFilter& filter = {}) const;
  std::optional<RunRecord> find_run(const std::string& run_id) const;
  // The unit's calibrations, oldest first (by date, then by entry order).
  std::vector<CalibrationRecord> unit_history(const std::string& serial) const;
  std::optional<CalibrationRecord> find_calibration(int64_t id) const;
  std::vector<CalibrationRecord> run_calibrations(const std::string& run_id) const;
  // The unit's acceptances, oldest first.
  std::vector<AcceptanceRecord> unit_acceptances(const std::string& serial) const;

  // PRAGMA integrity_check's answer ("ok" when sound).
  std::string integrity_check() const;
  int schema_version() const;

  // The connection, for tests and for later schema users; prefer the methods above.
  SQLite::Database& database() { return *db_; }

 private:
  void init_schema();
  std::filesystem::path path_;
  std::unique_ptr<SQLite::Database> db_;
};


}  // namespace fpss
