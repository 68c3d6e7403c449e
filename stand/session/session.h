// One `fpss-stand run`: bench (real or an emulator child), devices, run folder, engine, calibration, report, catalogue.
#pragma once
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procedures/settings.h"
#include "stand/contract/emulator_contract.h"
#include "stand/session/run_folder.h"
#include "stand/session/control_channel.h"
#include "stand/config/stand_config.h"
#include "procedures/engine.h"
#include "procedures/procedure.h"
#include "calib/samples.h"

namespace fpss {

struct Diagnosis;
class EmulatorProcess;
struct CoefficientSet;
// Fills a diagnosis's ambiguous sets' best_followup (stand/investigate's designer, which builds on
// sessions: the command line hands it in); empty: they stay null.
using FollowupPredictor = std::function<void(Diagnosis&, const CoefficientSet&)>;

struct SessionRequest {
  Procedure procedure;
  StandConfig stand;
  std::optional<EmulatorSpec> emulator;
  // Borrowed: an emulated bench already serving (investigate keeps one bench, its clock and its
  // environment going, across its runs); `emulator` then says how it was started, for the record.
  const EmulatorProcess* running_bench = nullptr;
  std::filesystem::path runs_dir = "runs";
  std::filesystem::path resume_dir;  // set: continue this run
  std::string catalogue;             // catalogue URL; "" : <runs_dir>/stand.db (a resume: the run folder's parent)
  double catch_up_s = 120;           // how long the run end retries a catalogue that was away
  bool tty = false;                  // draw the progress line
  bool quiet = false;                // no console log lines (tests)
  RunControl* control = nullptr;     // null: the session's own, driven by SIGINT/SIGTERM/SIGUSR1
  int keys_fd = -1;                  // a terminal (stdin): keys p pause, r resume, a abort (terminal_keys.h)
  // Asked through the run folder's control channel once the folder exists, before anything
  // moves; the run waits for the answers (docs/console.md). Kind "serial" must match the serial
  // the sensor reports, "confirm" must be yes (else the run is aborted), "text" must not be empty.
  std::vector<OperatorPrompt> prompts;
  std::string operator_name;  // recorded in run.json when given
  // false: the caller draws report.html itself, once, with what it adds (accept: the certificate),
  // from SessionResult::recording.
  bool write_report = true;
  // A diagnose step's ambiguous sets get their best_followup from it (the command line's designer).
  FollowupPredictor predict_followups;
};

struct SessionResult {
  int exit_code = 1;  // 0 completed, 1 failed or interrupted
  RunOutcome outcome = RunOutcome::failed;
  StopCause cause = StopCause::other;
  std::string reason;
  std::string catalogue_error;  // the catalogue could not record the run (the run folder is complete)
  std::filesystem::path run_dir;
  std::optional<std::filesystem::path> calibration, report;
  int64_t points_done = 0, points_total = 0;
  int64_t points_skipped = 0;  // of points_done: left out by a grid's adaptive stop
  EngineStats stats;
  double wall_s = 0;  // whole session, emulator start to report
  std::map<std::string, std::string> answers;  // the prompts' answers, by id
  std::string signed_off_utc;                  // when the last prompt was answered
  // Every row of the run (a resume's earlier rows too), as samples.csv holds them: the one
  // recording the session's calibrate steps fitted, handed on so nothing reads the file again.
  SampleTable recording;
  // Several units on the gimbal: each one's folder, recording, latest calibration and loss, in the
  // stand's order (`recording` above is then the first unit's). Empty for one unit.
  struct Unit {
    std::string serial;
    std::filesystem::path dir;
    std::optional<std::filesystem::path> calibration;
    std::optional<UnitLoss> loss;
    SampleTable recording;
  };
  std::vector<Unit> units;
};

// Throws InputError for bad input found before anything moved (invalid procedure or stand, a
// sensor reporting another serial than expected, a resume folder that does not match), and
// RunFolderBusy when another fpss-stand holds the run folder. `resume_dir` must be canonical
// (canonical_run_dir).
SessionResult run_session(const SessionRequest& req);

// The serial number in an ID? reply "FPSS,SN=<serial>,FW=<version>"; the whole reply otherwise.
std::string serial_from_id(const std::string& id_reply);

}  // namespace fpss
