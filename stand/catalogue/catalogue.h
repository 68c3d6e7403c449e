// The catalogue of units, runs, calibrations and acceptances: the interface and its records (docs/fleet.md).
#pragma once
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "procedures/events.h"

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

// What the engine knows when a run starts. The run id is run.json's `run_id`: a UUIDv7 for runs
// made since catalogues are shared by a fleet, the folder's name for older runs (docs/formats.md).
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
  std::string operator_name;       // who runs it (run.json's `operator`); "" when nobody was named
};

// The catalogue's text for a run's state: "running" until record_run_end gives it an outcome.
inline constexpr const char* kRunningName = "running";

struct RunRecord {
  std::string run_id;
  std::string unit;
  std::string procedure;
  std::string procedure_hash;
  std::string started_utc;
  std::optional<std::string> ended_utc;
  std::optional<RunOutcome> outcome;  // none while the run is running
  std::string run_dir;
  bool emulated = false;
  std::string stand;
  std::string software_version;
  int64_t resumes = 0;  // how many times the run was resumed
  int64_t pid = 0;      // process that last started or resumed it
  std::string host;     // and its host name: with run_dir, where the run folder lives
  std::string operator_name;  // who ran it (run.json's `operator`); "" when nobody was named
  // True when the run says `running` but its process is gone from this host (killed run): the
  // run folder's lock is not held (run_folder_owned), or, without the folder here, no process has
  // its pid. A run of another host is never called stale from here: its pid means nothing on this one.
  bool stale() const;
  bool running() const { return !outcome; }
  // "running" or the outcome's name, as the catalogue's column and the JSON outputs spell it.
  std::string outcome_name() const { return outcome ? to_string(*outcome) : kRunningName; }
  // From that text; InputError naming `where` for any other.
  static std::optional<RunOutcome> outcome_of(const std::string& name, const std::string& where);
};

// Whether a process holds the run folder's lock (RUN_DIR/.lock, taken by the run before it writes
// anything; the kernel drops it when its owner dies, however it dies): the run's process is alive,
// whatever became of its pid (pids are reused, 32768 of them on many machines). nullopt when this
// host cannot tell (no such folder here, /proc/locks unreadable).
std::optional<bool> run_folder_owned(const std::filesystem::path& run_dir);
// The run's process is alive: it holds the run folder's lock, or, when this host cannot tell, a
// process has its pid.
bool run_alive(const std::filesystem::path& run_dir, int64_t pid);

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
  std::string stand;                   // the stand that recorded it ("" when emulated without a stand file)
  std::string host;                    // the host that recorded it (set by the catalogue when empty)
  std::string operator_name;           // the operator of its run (run.json's `operator`); "" when none

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
  std::string stand;                   // the stand that judged it
  std::string host;                    // its host (set by the catalogue when empty)
  std::string operator_name;           // the operator of its run (run.json's `operator`); "" when none
};

struct RunFilter {
  std::optional<std::string> unit{};
  size_t limit = 0;  // 0: all; otherwise the most recent `limit`
};

// The catalogue's server cannot be reached (or the connection dropped) beyond the retry window: the
// run goes on recording to its folder and its entry catches up later (docs/fleet.md).
struct CatalogueUnavailable : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The catalogue: one interface, two backends with the same semantics (docs/fleet.md). SQLite, a
// file per stand, is the embedded default; PostgreSQL is one database a fleet of stands shares.
// An object owns one connection: give each thread its own.
class Catalogue {
 public:
  enum class Mode { read_write, read_only };
  // The schema version this software reads and writes; both backends number their migrations alike.
  static constexpr int kSchemaVersion = 3;

  virtual ~Catalogue() = default;

  // `runs/stand.db` under a runs folder: the default catalogue of `--runs-dir`.
  static std::filesystem::path default_path(const std::filesystem::path& runs_dir = "runs");

  // Where it is, for messages: the file's path, or the URL without its password.
  virtual std::string location() const = 0;
  virtual std::string backend() const = 0;  // "sqlite" or "postgresql"

  // Registers the unit if new. Returns true when it was new.
  virtual bool add_unit(const std::string& serial) = 0;

  // Inserts the run as `running`. Starting an existing run id again (a resume) keeps its
  // start time, sets it back to `running`, clears its end and counts the resume.
  virtual void record_run_start(const RunStart& run) = 0;
  // Sets the end time (empty: now) and outcome. Throws std::invalid_argument for an unknown run.
  virtual void record_run_end(const std::string& run_id, RunOutcome outcome,
                              const std::string& ended_utc = "") = 0;
  // Names the run's operator once it is known (an acceptance's prompt answers it after the run
  // started; a rebuild fills what an older schema did not keep): the run's, and that of its
  // calibrations and acceptances that name none. Returns how many records changed. Throws
  // std::invalid_argument for an unknown run.
  virtual int64_t record_run_operator(const std::string& run_id, const std::string& operator_name) = 0;
  // A whole run record as another catalogue holds it (catalogue copy): inserted when its id is
  // new, left as it is otherwise. Returns true when it was new.
  virtual bool copy_run(const RunRecord& run) = 0;
  // Returns the new calibration's id. Registers the unit; checks run_id exists when given.
  virtual int64_t record_calibration(const CalibrationRecord& cal) = 0;
  // An import (source "import") recorded unless the unit already holds an import of the same date
  // with the same coefficient JSON; check and insert are one transaction, so two processes
  // importing one file at once record it once. Returns the id and whether it was new.
  virtual std::pair<int64_t, bool> record_import_once(const CalibrationRecord& cal) = 0;
  virtual int64_t record_acceptance(const AcceptanceRecord& acc) = 0;

  virtual std::vector<std::string> units() const = 0;
  virtual bool has_unit(const std::string& serial) const = 0;
  // Most recent first.
  virtual std::vector<RunRecord> list_runs(const RunFilter& filter = {}) const = 0;
  virtual std::optional<RunRecord> find_run(const std::string& run_id) const = 0;
  // The unit's calibrations, oldest first (by date, then by entry order).
  virtual std::vector<CalibrationRecord> unit_history(const std::string& serial) const = 0;
  virtual std::optional<CalibrationRecord> find_calibration(int64_t id) const = 0;
  virtual std::vector<CalibrationRecord> run_calibrations(const std::string& run_id) const = 0;
  // The unit's acceptances, oldest first.
  virtual std::vector<AcceptanceRecord> unit_acceptances(const std::string& serial) const = 0;

  // "ok" when sound (SQLite's integrity_check; PostgreSQL: the connection answers).
  virtual std::string integrity_check() const = 0;
  virtual int schema_version() const = 0;
};

// Opens a catalogue by URL: `sqlite:PATH`, a plain PATH (SQLite too), or
// `postgresql://USER@HOST[:PORT]/DB?sslmode=...` (also `postgres://`). Read-write applies the
// schema's migrations on first use; both modes refuse a newer schema with InputError.
std::unique_ptr<Catalogue> open_catalogue(const std::string& url, Catalogue::Mode mode = Catalogue::Mode::read_write);

// The URL without its password (user:password@ or password=), for messages and files.
std::string url_for_messages(const std::string& url);

// True for a postgresql:// or postgres:// URL.
bool is_postgres_url(const std::string& url);

// The host name this process runs on ("" when unknown): every record names it.
std::string this_host();

}  // namespace fpss
