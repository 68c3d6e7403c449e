// A run folder as a whole: its one owner at a time (flock), its canonical path, and what run.json holds.
#pragma once
#include <filesystem>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "base/unique_fd.h"
#include "stand/catalogue/rebuild.h"  // kCataloguePending
#include "stand/catalogue/run_file.h"
#include "stand/contract/emulator_contract.h"

namespace fpss {

// The one spelling of a run folder (trailing slash, relative path and symlinks resolved), so every
// spelling refers to the same run and the same catalogue. InputError when it is not a folder.
std::filesystem::path canonical_run_dir(const std::filesystem::path& dir);

// An exclusive lock on a run folder (flock on RUN_DIR/.lock, which holds the owner's pid), held
// while a run or a resume writes into it. A second owner is refused with RunFolderBusy, before
// it writes anything. The kernel drops the lock when the owner dies, however it dies.
struct RunFolderBusy : std::runtime_error {
  using std::runtime_error::runtime_error;
};
class RunFolderLock {
 public:
  explicit RunFolderLock(const std::filesystem::path& run_dir);  // throws RunFolderBusy
  // The same lock on `dir`/`file` for another single owner (`what`, for the message), e.g. the
  // one console of a runs folder.
  RunFolderLock(const std::filesystem::path& dir, const std::string& file, const std::string& what);
  ~RunFolderLock();
  RunFolderLock(const RunFolderLock&) = delete;
  RunFolderLock& operator=(const RunFolderLock&) = delete;

 private:
  UniqueFd fd_;  // closing it releases the flock
};

// What a run folder's run.json holds (for --resume and tools).
struct RunInfo {
  RunFile run;
  std::string procedure_text, procedure_origin, stand_text, stand_origin;
  std::optional<EmulatorSpec> emulator;
};
RunInfo read_run_info(const std::filesystem::path& run_dir);

// A new run id, unique across the stands of a fleet: a UUIDv7 (RFC 9562; 48-bit Unix time in ms,
// then 74 random bits), so ids also sort by start time. The run folder keeps its readable name.
std::string new_run_id();

// RUN_DIR/catalogue.pending: the catalogue missed something of this run (the server was away).
// The run end, the next run on the same runs folder and `catalogue rebuild` re-index the folder
// and remove the mark (docs/fleet.md).
void mark_catalogue_pending(const std::filesystem::path& run_dir, const std::string& catalogue,
                            const std::string& what, const std::string& error);

}  // namespace fpss
