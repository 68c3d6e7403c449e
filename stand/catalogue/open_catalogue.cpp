// The catalogue chosen by URL (sqlite:PATH, a plain path, postgresql://...), and what both backends share.
#include <fmt/format.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <cerrno>
#include <fstream>
#include <sstream>

#include "base/errors.h"
#include "stand/catalogue/catalogue.h"
#include "stand/catalogue/postgres_catalogue.h"
#include "stand/catalogue/sqlite_catalogue.h"

namespace fpss {

namespace fs = std::filesystem;

std::string this_host() {
  char buf[256] = {};
  if (::gethostname(buf, sizeof buf - 1) != 0) return "";
  return buf;
}

std::optional<bool> run_folder_owned(const fs::path& run_dir) {
  struct stat st {};
  if (::stat((run_dir / ".lock").c_str(), &st) != 0) return std::nullopt;
  std::ifstream locks("/proc/locks");
  if (!locks) return std::nullopt;
  // "1: FLOCK  ADVISORY  WRITE 5431 fe:00:10953392 0 EOF" (device major:minor in hex, inode).
  // Any kind of lock (a network file system may hold an flock as a POSIX lock): only the run, or
  // a catalogue catch-up for a moment, locks that file. "1: -> FLOCK ..." is a waiter, not a holder.
  const std::string id = fmt::format("{:02x}:{:02x}:{}", major(st.st_dev), minor(st.st_dev), st.st_ino);
  std::string line;
  while (std::getline(locks, line)) {
    std::istringstream in(line);
    std::string n, kind, advisory, mode, pid, dev;
    in >> n >> kind >> advisory >> mode >> pid >> dev;
    if (kind != "->" && dev == id) return true;
  }
  return false;
}

bool run_alive(const fs::path& run_dir, int64_t pid) {
  if (const auto owned = run_folder_owned(run_dir)) return *owned;
  return pid > 0 && (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM);
}

bool RunRecord::stale() const {
  if (!running() || pid <= 0 || host.empty() || host != this_host()) return false;
  return !run_alive(run_dir, pid);
}

std::optional<RunOutcome> RunRecord::outcome_of(const std::string& name, const std::string& where) {
  if (name == kRunningName) return std::nullopt;
  if (auto o = parse_outcome(name)) return o;
  throw InputError(fmt::format("{}: run outcome \"{}\" (expected running, completed, failed or interrupted)", where, name));
}

fs::path Catalogue::default_path(const fs::path& runs_dir) { return runs_dir / "stand.db"; }

bool is_postgres_url(const std::string& url) {
  return url.rfind("postgresql://", 0) == 0 || url.rfind("postgres://", 0) == 0;
}

std::unique_ptr<Catalogue> open_catalogue(const std::string& url, Catalogue::Mode mode) {
  if (url.empty()) throw InputError("--catalogue: empty");
  if (url.size() > 4096) throw InputError(fmt::format("--catalogue: {} characters, more than 4096", url.size()));
  if (is_postgres_url(url)) return std::make_unique<PostgresCatalogue>(url, mode);
  std::string path = url;
  if (url.rfind("sqlite:", 0) == 0) {
    path = url.substr(7);
    if (path.rfind("//", 0) == 0) path = path.substr(2);  // sqlite:///abs/path as well as sqlite:/abs/path
    if (path.empty()) throw InputError(fmt::format("--catalogue {}: sqlite: needs a file path", url));
  } else if (const auto colon = url.find("://"); colon != std::string::npos) {
    throw InputError(fmt::format("--catalogue {}: unknown scheme \"{}\" (sqlite:PATH or postgresql://...)", url,
                                 url.substr(0, colon)));
  }
  return std::make_unique<SqliteCatalogue>(path, mode);
}

}  // namespace fpss
