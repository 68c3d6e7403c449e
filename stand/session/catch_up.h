// A run folder's catalogue entry catching up after the catalogue was away (the pending mark).
#pragma once
#include <filesystem>
#include <string>

namespace fpss {

// Re-indexes `run_dir` into the catalogue at `url` (runs, calibrations, acceptance: idempotent),
// trying again until it succeeds or `window_s` has passed; on success removes the folder's
// catalogue.pending and returns "" , otherwise the last error.
std::string catch_up_run(const std::string& url, const std::filesystem::path& run_dir, double window_s);

// Every folder under `runs_dir` that holds a catalogue.pending, caught up once each (no waiting):
// what the next run on a runs folder does for the ones before it. Returns how many caught up.
int catch_up_pending(const std::string& url, const std::filesystem::path& runs_dir);

}  // namespace fpss
