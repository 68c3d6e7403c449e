// Re-indexing run folders into the catalogue, so nothing recorded on disk is ever lost to the index.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "stand/catalogue/catalogue.h"

namespace fpss {

// RUN_DIR/catalogue.pending: the catalogue missed something of this run while it was away. Indexing
// the folder (a rebuild, a run's catch-up) removes it.
inline constexpr const char* kCataloguePending = "catalogue.pending";

struct RebuildReport {
  int folders = 0;                 // run folders seen (a run.json)
  int runs_added = 0, runs_updated = 0, calibrations_added = 0, acceptances_added = 0;
  int operators_named = 0;         // known runs whose operator the folder names and the catalogue did not
  std::vector<std::string> skipped;  // "<folder>: why", for folders that could not be read
};

// Brings the catalogue up to what the run folders under `runs_dir` hold: every run (run.json: its
// start, end and outcome), every calibration (calibration.json, calibration-N.json) and every
// acceptance (acceptance.json), and removes their catalogue.pending marks. Idempotent: what is already indexed is left as it is; a run the
// catalogue still calls `running` takes the outcome its folder records, and a run whose operator the
// catalogue lacks (a catalogue older than schema version 3) takes run.json's `operator`, as do its
// calibrations and acceptances.
RebuildReport rebuild_catalogue(Catalogue& cat, const std::filesystem::path& runs_dir);

// The same for one run folder (a run's entry catching up after the catalogue was away); throws
// what reading the folder or the catalogue throws.
void index_run_folder(Catalogue& cat, const std::filesystem::path& dir, RebuildReport& report);

}  // namespace fpss
