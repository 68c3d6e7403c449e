// A run's diagnose step: the sim-to-real diagnosis of the rows recorded so far, into the run folder.
#pragma once
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

#include <spdlog/logger.h>

#include <utility>
#include <vector>

#include "calib/diagnosis/diagnosis.h"
#include "calib/samples.h"
#include "stand/session/session.h"
#include "stand/session/session_units.h"
#include "procedures/procedure.h"

namespace fpss {

struct DiagnoseStepResult {
  std::filesystem::path json, html;  // GAP.json and GAP.html (GAP-2.json, ... for later steps)
  std::string verdict, sentence, cause;
  bool incomplete = false;  // the recording cannot tell every effect apart (see not_observable)
  Diagnosis diagnosis{};    // what the files hold (several units: attributed to the stand or the unit)
};

// Diagnoses the run's recording (the session's, in memory) up to step `last_step` (the points
// before the diagnose step) against the step's model: the same columns `fpss-stand diagnose --data`
// reads from samples.csv (temperature_c from the provenance). `nth` counts the run's diagnose steps
// from 1. Both files are written atomically. Throws InputError when the rows cannot be diagnosed.
// `model`: the step's model, or (several units) this unit's.
DiagnoseStepResult run_diagnose_step(const SampleTable& recording, int64_t last_step, const DiagnoseStep& step,
                                     const std::filesystem::path& run_dir, int nth,
                                     const std::filesystem::path& model = {}, const FollowupPredictor& predict = {});

// Several units: what is the stand's and what each unit's (calib/diagnosis/joint.h), as
// `diagnose --run ... --out` writes it.
nlohmann::ordered_json joint_diagnosis_json(const std::vector<std::pair<std::string, Diagnosis>>& units,
                                            const std::string& run_id);
// The same written as RUN_DIR/GAP.json (GAP-N.json for later steps).
std::filesystem::path write_joint_diagnosis(const std::vector<std::pair<std::string, Diagnosis>>& units,
                                            const std::filesystem::path& run_dir, int nth, const std::string& run_id);

// A run's diagnose step over its units: each unit still read against its model (the step's
// `models` by serial, else its `model`; a unit with neither is left out, logged) into its folder,
// then, for several units, the stand-or-unit attribution into RUN_DIR/GAP.json. Returns the file
// run.json names (the single unit's GAP.json, or the attribution); empty when nothing was diagnosed.
std::filesystem::path diagnose_units(const std::vector<SessionUnit>& units, int64_t last_step, const DiagnoseStep& step,
                                     const std::filesystem::path& run_dir, int nth, const std::string& run_id,
                                     spdlog::logger& log, const FollowupPredictor& predict = {});

}  // namespace fpss
