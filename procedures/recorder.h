// The run folder's durable records: samples.csv appended and synced per point, the point journal, run.json.
#pragma once
#include <cstdint>
#include <filesystem>
#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/json_file.h"
#include "base/unique_fd.h"
#include "calib/samples.h"

namespace fpss {

// Columns the recorder writes after the samples contract's, in this order.
const std::vector<std::string>& recorder_extra_columns();

// One recorded row: the contract's columns and the recorder's extras.
struct RecordedRow {
  Sample sample;
  double sensor_time_s = 0;   // the sensor's clock (unwrapped)
  uint16_t frame_seq = 0;
  uint8_t sensor_status = 0;
  double host_time_s = 0;     // host steady clock at receipt, seconds since the session started
  double gimbal_time_s = 0;   // the gimbal's clock at the reference (slews: interpolated to the frame)
  double gimbal_pitch_arcsec = 0, gimbal_yaw_arcsec = 0;  // stand frame, encoders
  uint16_t gimbal_status = 0;
  double target_pitch_arcsec = 0, target_yaw_arcsec = 0;  // stand frame
  double temperature_c = 0;   // NaN when the sensor did not answer
  int attempt = 1;            // measurement attempt of the point that was kept
  int session = 1;            // 1 + number of resumes before this row
  int unit = 0;               // which unit of the stand (its index in the stand's units); not a column
  // Dwells: the row's time less the gimbal's arrival (the arrival the settle counts from, on the
  // gimbal's clock); NaN (empty) in slews, which are moving.
  double time_since_move_s = std::numeric_limits<double>::quiet_NaN();
  // Dwells: the side each axis last came from, in the samples' (sensor) frame, +1, -1 or 0 before
  // any motion (MoveScheduler::approach); NaN (empty) in slews.
  double approach_pitch = std::numeric_limits<double>::quiet_NaN();
  double approach_yaw = std::numeric_limits<double>::quiet_NaN();
  // The recorder's columns as numbers (temperature NaN when not answered), in their order.
  std::vector<double> provenance() const;
  // The same as samples.csv writes them ("" for NaN).
  std::vector<std::string> extras() const;
};

// What the journal says about one completed point.
struct JournalEntry {
  int64_t point = 0;     // plan index (0-based); points.jsonl writes it 1-based, as `point`
  int64_t step = 0;      // the samples file's step column (point + 1)
  size_t rows = 0;       // rows of this point
  uint64_t bytes = 0;    // samples.csv size once this point was synced
  double last_time_s = 0;
  std::string utc;
  int session = 1;
  int attempts = 1;
  // Not measured: why ("until": a grid's adaptive stop had reached its target); rows is then 0.
  std::string skipped;
  // Several units: each unit's samples.csv size once this point was synced (bytes is the first's).
  std::vector<uint64_t> unit_bytes;
};

// A unit's folder name in RUN_DIR/units/: its serial, with anything but letters, digits, '.', '_'
// and '-' replaced by '_' ("unknown" when empty).
std::string unit_folder_name(const std::string& serial);


// An ISO 8601 UTC time (utc_now_iso(), 2024-05-01T12:00:00Z) compact for folder names (20240501T120000Z).
std::string utc_compact(const std::string& iso);

// A fresh folder <runs_dir>/<UTC time>-<unit>-<procedure>/ (a suffix -2, -3, ... if taken).
std::filesystem::path make_run_dir(const std::filesystem::path& runs_dir, const std::string& utc_iso,
                                   const std::string& unit, const std::string& procedure);

// Writes JSON atomically (temporary file, fsync, rename): a crash leaves the old or the new file.
void write_json_atomic(const std::filesystem::path& path, const nlohmann::json& j);
// JSON files are read with base/json_file.h's read_json_file (size, depth, duplicate keys).

// Where a run continues: the first point not yet durable, the last row's time and when it was journalled.
struct ResumePoint {
  int64_t next_point = 0;
  double last_time_s = 0;
  std::string last_utc;  // "" for a new run
};

// Appends points to samples.csv and records each in points.jsonl once it is durable, so a crash
// loses at most the point in progress. Opening an existing folder (a resume) cuts samples.csv
// back to the end of the last journalled point: no half point survives, none is repeated.
// Several units: each unit's rows (RecordedRow::unit) go to RUN_DIR/units/<SERIAL>/samples.csv,
// all synced before the point is journalled; the journal gives every file's size (unit_bytes).
class RunRecorder {
 public:
  // `unit_serials`: several units' serials in the stand's order; empty or one: RUN_DIR/samples.csv.
  explicit RunRecorder(const std::filesystem::path& run_dir, std::vector<std::string> unit_serials = {});
  RunRecorder(const RunRecorder&) = delete;
  RunRecorder& operator=(const RunRecorder&) = delete;

  // Appends the rows of one point, syncs samples.csv, then journals the point.
  void append_point(int64_t point, const std::vector<RecordedRow>& rows, int attempts, int session);

  // Journals a point that will not be measured (no rows), so that the points stay in order.
  void skip_point(int64_t point, int session, const std::string& why);

  const std::vector<JournalEntry>& journal() const { return journal_; }
  int64_t next_point() const { return journal_.empty() ? 0 : journal_.back().point + 1; }
  double last_time_s() const { return last_time_s_; }
  ResumePoint resume_point() const {
    return {next_point(), last_time_s_, journal_.empty() ? std::string() : journal_.back().utc};
  }
  bool has_rows() const { return has_rows_; }
  size_t rows() const { return writers_.front()->rows_written(); }  // the first unit's
  // Bytes of a torn point cut away when the folder was opened (0 on a clean open).
  uint64_t cut_bytes() const { return cut_bytes_; }
  const std::filesystem::path& dir() const { return dir_; }
  // The first unit's samples.csv (the only one with one unit).
  std::filesystem::path samples_path() const { return samples_path(0); }
  std::filesystem::path samples_path(size_t unit) const;
  size_t units() const { return std::max<size_t>(1, serials_.size()); }
  std::filesystem::path journal_path() const { return dir_ / "points.jsonl"; }

  // Reads the journal, ignoring a torn or unreadable last line; InputError for anything else
  // malformed (a gap, a repeat, a bad line followed by good ones).
  static std::vector<JournalEntry> read_journal(const std::filesystem::path& path);

 private:
  std::filesystem::path dir_;
  std::vector<std::string> serials_;  // several units; empty for one
  std::vector<std::unique_ptr<SamplesCsvWriter>> writers_;  // every unit's (several units)
  void open_samples(size_t unit, uint64_t keep);
  std::vector<JournalEntry> journal_;
  UniqueFd journal_fd_;
  double last_time_s_ = 0;
  bool has_rows_ = false;
  uint64_t cut_bytes_ = 0;

  void journal_point(int64_t point, size_t rows, int attempts, int session, const std::string& skipped);

 public:
  ~RunRecorder();
};

}  // namespace fpss
