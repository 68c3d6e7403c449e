// run.json, the run folder's summary (docs/formats.md), as one type: the session writes it, every
// reader (resume, show, report, accept, the console, catalogue rebuild) reads it through from_json.
#pragma once
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procedures/events.h"  // StopCause

namespace fpss {

// run.json's `format`.
inline constexpr const char* kRunFileFormat = "fpss-stand run/1";

// One entry of `sessions`: a start or a resume. Every key but `session` may be absent (the
// session's end is written when it ends).
struct RunFileSession {
  int64_t session = 1;
  std::optional<std::string> started_utc, ended_utc, outcome, reason;
  std::optional<int64_t> first_point;  // 1-based
  std::optional<int64_t> pid, points_completed;
  std::optional<nlohmann::json> engine;        // the engine's timings (objects as written)
  std::optional<nlohmann::json> sensor_stats;  // the sensor link's counters
  std::optional<nlohmann::json> emulator;      // {"command", "gimbal", "sensor"} of an emulated bench
};

// One entry of `adaptive_stops`: the step_stopped event's fields (events.jsonl).
struct RunFileAdaptiveStop {
  int64_t step = 0;
  std::string axes;
  std::optional<double> sigma_max_arcsec;  // null: not known
  double until_sigma_arcsec = 0;
  int64_t points_skipped = 0;
  std::optional<int64_t> first_skipped_point;  // null: none
  std::string reason;
  static RunFileAdaptiveStop of(const StepStopped& s);
};

// `acceptance`, written by `fpss-stand accept`.
struct RunFileAcceptance {
  std::optional<std::string> file, certificate;
  std::string verdict;  // pass | conditional | fail
  std::optional<std::vector<std::string>> failed;
  struct Limits {
    std::string file, sha256;
  };
  std::optional<Limits> limits;
};

// `reference`: the reference calibration file the run applied to its reference angles
// (calib/reference_calibration.h), as named by its identity().
struct RunFileReference {
  std::string file, sha256, certificate, date, lab;
};

// How a unit sits relative to the run's first unit (several units): its boresight offset and
// roll, arcsec, each with its 1-sigma (calib/unit_alignment.h).
struct RunFileRelative {
  std::string to;  // the first unit's serial
  double boresight_pitch_arcsec = 0, boresight_pitch_sigma_arcsec = 0;
  double boresight_yaw_arcsec = 0, boresight_yaw_sigma_arcsec = 0;
  double roll_arcsec = 0, roll_sigma_arcsec = 0;
};

// One entry of `units` (several units on one gimbal): a unit's outcome and its files, relative
// to the run folder (units/<SERIAL>/...).
struct RunFileUnit {
  std::string serial;
  std::optional<std::string> sensor_id, endpoint;
  std::string outcome = "running";          // running | completed | lost | failed | interrupted
  std::optional<std::string> loss_cause;    // lost: silence | crc_storm | invalid_frames | wrong_serial | link_failed
  std::optional<std::string> reason;        // lost: what happened
  std::optional<int64_t> lost_at_point;     // lost: the point (1-based) it was dropped at; 0 before the first
  std::optional<std::string> samples, calibration, acceptance, certificate;
  std::optional<std::string> verdict;       // accept: pass | conditional | fail
  std::optional<RunFileRelative> relative;  // every unit but the first, once calibrated
};

struct RunFile {
  std::optional<std::string> format;  // kRunFileFormat
  std::optional<std::string> run_id;  // a UUIDv7; older runs: absent (the folder's name)
  struct Software {
    std::string name, version;
  };
  std::optional<Software> software;
  struct Procedure {
    std::string name, sha256, text;
    std::optional<std::string> file;
  } procedure;
  struct Stand {
    std::optional<std::string> file, text;  // written as null when there is none
    nlohmann::json settings;                 // the settings in effect (stand/config's to_json)
  };
  std::optional<Stand> stand;
  std::string unit;
  std::optional<std::string> sensor_id;
  bool emulated = false;
  std::optional<nlohmann::json> emulator;  // the emulator's bench settings (EmulatorSpec::to_json)
  std::string started_utc;
  std::optional<std::string> ended_utc;
  std::string outcome = "running";  // running | completed | failed | interrupted
  std::optional<std::string> reason;
  std::optional<StopCause> stop_cause;
  struct Points {
    int64_t total = 0, completed = 0;
    std::optional<int64_t> skipped;
  } points;
  std::optional<std::vector<RunFileAdaptiveStop>> adaptive_stops;
  std::optional<bool> safe_state;
  std::optional<std::string> operator_name;  // `operator`
  std::optional<std::string> signed_off_utc;
  std::vector<RunFileSession> sessions;
  struct Files {
    std::optional<std::string> samples, journal, events, event_stream, calibration, gap;
  } files;
  std::optional<RunFileAcceptance> acceptance;
  std::optional<RunFileReference> reference;  // absent: the readings were taken as true
  std::optional<std::vector<RunFileUnit>> units;  // several units on one gimbal; absent for one
  nlohmann::json extra = nlohmann::json::object();  // keys this version does not know, kept as read

  // The run id, or the folder's name for runs made before ids were UUIDs.
  std::string id_or(const std::filesystem::path& run_dir) const;
};

// The run's acceptance verdict as the runs lists show it (pass | conditional | fail): `acceptance`'s;
// several units: the worst unit's (a lost unit fails); none before any verdict.
std::optional<std::string> acceptance_verdict(const RunFile& run);

// The file's JSON: the same keys and values the session has always written (nlohmann::json keeps
// keys sorted, so the bytes are the same too).
nlohmann::json to_json(const RunFile& r);
nlohmann::json to_json(const RunFileUnit& u);  // one entry of `units`, as the file has it
// InputError "<origin>: key \"k\": ..." for a key missing or of the wrong type or value.
RunFile run_file_from_json(const nlohmann::json& j, const std::string& origin);
// Reads RUN_DIR/run.json (base/json_file.h's limits); InputError naming the file and the key.
RunFile read_run_file(const std::filesystem::path& run_dir);
// Writes RUN_DIR/run.json atomically.
void write_run_file(const std::filesystem::path& run_dir, const RunFile& r);

}  // namespace fpss
