// Re-indexing run folders into the catalogue, so nothing recorded on disk is ever lost to the index.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "stand/catalogue/catalogue.h"

namespace fpss {

struct RebuildReport {
  int folders = 0;                 // run folders seen (a run.json)
  int runs_added = 0, runs_updated = 0, calibrations_added = 0, acceptances_added = 0;
  std::vector<std::string> skipped;  // "<folder>: why", for folders that could not be read
};

// Brings the catalogue up to what the run folders under `runs_dir` hold: every run (run.json: its
// start, end and outcome), every calibration (calibration.json, calibration-N.json) and every
// acceptance (acceptance.json). Idempotent: what is already indexed is left as it is; a run the
// catalogue still calls `running` takes the outcome its folder records.
RebuildReport rebuild_catalogue(Catalogue& cat, const std::filesystem::path& runs_dir);

}  // namespace fpss
