// A run folder as a whole: its one owner at a time (flock), its canonical path, and what run.json holds.
#pragma once
#include <filesystem>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "stand/cli/emulator_contract.h"

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
  ~RunFolderLock();
  RunFolderLock(const RunFolderLock&) = delete;
  RunFolderLock& operator=(const RunFolderLock&) = delete;

 private:
  int fd_ = -1;
};

// What a run folder's run.json holds (for --resume and tools).
struct RunInfo {
  nlohmann::json doc;
  std::string procedure_text, procedure_origin, stand_text, stand_origin;
  std::optional<EmulatorSpec> emulator;
};
RunInfo read_run_info(const std::filesystem::path& run_dir);

}  // namespace fpss
