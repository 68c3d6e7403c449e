// A run's diagnose step: the sim-to-real diagnosis of the rows recorded so far, into the run folder.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>

#include "procedures/procedure.h"

namespace fpss {

struct DiagnoseStepResult {
  std::filesystem::path json, html;  // GAP.json and GAP.html (GAP-2.json, ... for later steps)
  std::string verdict, sentence, cause;
  bool incomplete = false;  // the recording cannot tell every effect apart (see not_observable)
};

// Diagnoses the rows of `samples_csv` up to step `last_step` (the points before the diagnose step)
// against the step's model, read straight into the diagnosis's columns (no table of every column,
// no copy); `nth` counts the run's diagnose steps from 1. Both files are written atomically.
// Throws InputError when the rows cannot be diagnosed.
DiagnoseStepResult run_diagnose_step(const std::filesystem::path& samples_csv, int64_t last_step,
                                     const DiagnoseStep& step, const std::filesystem::path& run_dir, int nth);

}  // namespace fpss
