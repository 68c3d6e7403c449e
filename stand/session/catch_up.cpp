// A run folder's catalogue entry catching up: re-index the folder, retried within a window, then drop the pending mark.
#include "stand/session/catch_up.h"

#include <chrono>
#include <system_error>
#include <thread>

#include "stand/catalogue/catalogue.h"
#include "stand/catalogue/rebuild.h"
#include "stand/session/run_folder.h"

namespace fpss {

namespace fs = std::filesystem;

std::string catch_up_run(const std::string& url, const fs::path& run_dir, double window_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(window_s);
  std::string error;
  for (;;) {
    try {
      auto cat = open_catalogue(url);
      RebuildReport r;
      index_run_folder(*cat, run_dir, r);
      std::error_code ec;
      fs::remove(run_dir / kCataloguePending, ec);
      return "";
    } catch (const std::exception& e) {
      error = e.what();
    }
    if (std::chrono::steady_clock::now() >= deadline) return error;
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
}

int catch_up_pending(const std::string& url, const fs::path& runs_dir) {
  int done = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(runs_dir, ec)) {
    if (!e.is_directory() || e.is_symlink() || !fs::exists(e.path() / kCataloguePending)) continue;
    try {
      RunFolderLock lock(e.path());  // a folder a run still writes to is that run's business
      if (catch_up_run(url, e.path(), 0).empty()) ++done;
    } catch (const RunFolderBusy&) {
    }
  }
  return done;
}

}  // namespace fpss
