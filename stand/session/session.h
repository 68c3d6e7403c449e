// One `fpss-stand run`: bench (real or an emulator child), devices, run folder, engine, calibration, report, catalogue.
#pragma once
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procedures/settings.h"
#include "stand/cli/emulator_contract.h"
#include "stand/session/run_folder.h"
#include "stand/config/stand_config.h"
#include "procedures/engine.h"
#include "procedures/procedure.h"

namespace fpss {

struct SessionRequest {
  Procedure procedure;
  StandConfig stand;
  std::optional<EmulatorSpec> emulator;
  std::filesystem::path runs_dir = "runs";
  std::filesystem::path resume_dir;  // set: continue this run
  std::string catalogue;             // catalogue URL; "" : <runs_dir>/stand.db (a resume: the run folder's parent)
  double catch_up_s = 120;           // how long the run end retries a catalogue that was away
  bool tty = false;                  // draw the progress line
  bool quiet = false;                // no console log lines (tests)
  RunControl* control = nullptr;     // null: the session's own, driven by SIGINT/SIGTERM/SIGUSR1
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
  EngineStats stats;
  double wall_s = 0;  // whole session, emulator start to report
};

// Throws InputError for bad input found before anything moved (invalid procedure or stand, a
// sensor reporting another serial than expected, a resume folder that does not match), and
// RunFolderBusy when another fpss-stand holds the run folder. `resume_dir` must be canonical
// (canonical_run_dir).
SessionResult run_session(const SessionRequest& req);

// The serial number in an ID? reply "FPSS,SN=<serial>,FW=<version>"; the whole reply otherwise.
std::string serial_from_id(const std::string& id_reply);

}  // namespace fpss
