// A run's diagnose step: the sim-to-real diagnosis of the rows recorded so far, into the run folder.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>

#include "calib/samples.h"
#include "procedures/procedure.h"

namespace fpss {

struct DiagnoseStepResult {
  std::filesystem::path json, html;  // GAP.json and GAP.html (GAP-2.json, ... for later steps)
  std::string verdict, sentence, cause;
  bool incomplete = false;  // the recording cannot tell every effect apart (see not_observable)
};

// Diagnoses the run's recording (the session's, in memory) up to step `last_step` (the points
// before the diagnose step) against the step's model: the same columns `fpss-stand diagnose --data`
// reads from samples.csv (temperature_c from the provenance). `nth` counts the run's diagnose steps
// from 1. Both files are written atomically. Throws InputError when the rows cannot be diagnosed.
DiagnoseStepResult run_diagnose_step(const SampleTable& recording, int64_t last_step, const DiagnoseStep& step,
                                     const std::filesystem::path& run_dir, int nth);

}  // namespace fpss
