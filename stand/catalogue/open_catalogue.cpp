// The catalogue chosen by URL (sqlite:PATH, a plain path, postgresql://...), and what both backends share.
#include <fmt/format.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>

#include "calib/errors.h"
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

bool RunRecord::stale() const {
  if (outcome != outcome::running || pid <= 0 || host.empty() || host != this_host()) return false;
  return ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH;
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
