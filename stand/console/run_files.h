// What the console reads of the runs folder: live runs, a run's folder and files, its events.jsonl from an offset.
#pragma once
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stand/catalogue/catalogue.h"
#include "stand/console/catalogue_pool.h"

namespace fpss::console {

// A run the catalogue knows: its folder (from the catalogue, never from the request) and whether
// its process is alive on this host.
struct RunRef {
  std::string run_id;
  std::filesystem::path dir;
  bool live = false;
  int pid = 0;
};
// Each reads the console's catalogue (serve --catalogue, or RUNS_DIR/stand.db) through its pool.
std::optional<RunRef> find_run(CataloguePool& catalogue, const std::string& run_id);
// Runs whose process is alive (at most one on a stand, but any number is listed).
std::vector<RunRef> live_runs(CataloguePool& catalogue);
// The run started by process `pid` (a job's child, spawned at spawned_utc), once it is in the
// catalogue. Pids are reused (32768 of them on many machines, soon wrapped on a busy one): a run
// of an earlier process with the same pid, started before the spawn's second, is not it.
std::optional<RunRef> run_of_pid(CataloguePool& catalogue, int pid, const std::string& spawned_utc);

// The catalogue's runs, most recent first, filtered (empty filter: all); run.json's outcome,
// points and acceptance verdict added for each.
nlohmann::json runs_json(CataloguePool& catalogue, const std::string& unit, const std::string& outcome,
                         const std::string& from_date, const std::string& to_date, size_t limit);
// run.json with the files present and links.
nlohmann::json run_json(const RunRef& r);

// Complete lines of events.jsonl from byte `offset`, at most `max_bytes`; `next` is the offset
// after the last complete line returned (a line being written is left for next time).
struct EventChunk {
  std::vector<std::string> lines;
  std::vector<uint64_t> ends;  // offset after each line (the SSE id)
  uint64_t next = 0;
};
EventChunk read_events(const std::filesystem::path& run_dir, uint64_t offset, size_t max_bytes = 256 * 1024);

// A file of a run folder by its relative path: segments of [A-Za-z0-9._-] not starting with a
// dot, a regular file (no symlink) inside the folder. nullopt otherwise.
std::optional<std::filesystem::path> run_file(const std::filesystem::path& run_dir, const std::string& rel);

// The investigations of the runs folder (`investigate`'s default --out and the console's jobs put
// them there: RUNS/investigation-*/INVESTIGATION.json), most recent first (their names carry the
// UTC time), at most `limit`: name, stop reason, verdict, cause(s), still ambiguous, unbounded,
// runs (ids), bench time and links to its files. A folder whose record is missing, unreadable
// (being written) or over 2 MiB is left out.
nlohmann::json investigations_json(const std::filesystem::path& runs_dir, size_t limit = 200);
// An investigation's folder by its name (investigation-[A-Za-z0-9._-]+, a real folder directly in
// runs_dir, not a link); nullopt otherwise.
std::optional<std::filesystem::path> investigation_dir(const std::filesystem::path& runs_dir, const std::string& name);

}  // namespace fpss::console
