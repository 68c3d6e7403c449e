#include "stand/cli/run_lookup.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <tuple>

#include "base/errors.h"
#include "stand/catalogue/catalogue.h"
#include "stand/catalogue/run_file.h"
#include "stand/cli/terminal.h"

namespace fpss::cli {

namespace fs = std::filesystem;

namespace {

// Folders holding a stand.db below `root`, at most `depth` folders down; hidden and CMake's own
// folders are skipped, and the walk stops after `budget` entries so a huge tree cannot stall it.
void catalogues_below(const fs::path& root, int depth, size_t& budget, std::vector<fs::path>& out) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(root, fs::directory_options::skip_permission_denied, ec)) {
    if (budget == 0) return;
    --budget;
    const std::string name = e.path().filename().string();
    if (name.empty() || name[0] == '.' || name == "CMakeFiles" || e.is_symlink(ec) || !e.is_directory(ec)) continue;
    if (fs::is_regular_file(e.path() / "stand.db", ec)) out.push_back(e.path());
    if (depth > 1) catalogues_below(e.path(), depth - 1, budget, out);
  }
}

fs::file_time_type written(const fs::path& dir) {
  std::error_code ec;
  const auto t = fs::last_write_time(dir / "stand.db", ec);
  return ec ? fs::file_time_type::min() : t;
}

struct RunEntry {
  fs::path dir;
  std::string name, id, started_utc;
};

std::vector<RunEntry> runs_in(const fs::path& runs_dir) {
  std::vector<RunEntry> runs;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(runs_dir, ec)) {
    if (!e.is_directory() || e.is_symlink() || !fs::is_regular_file(e.path() / "run.json")) continue;
    RunEntry r{e.path(), e.path().filename().string(), e.path().filename().string(), ""};
    try {
      const RunFile run = read_run_file(e.path());
      r.id = run.id_or(e.path());
      r.started_utc = run.started_utc;
    } catch (const InputError&) {
      // a run.json that does not read: still found by its folder's name
    }
    runs.push_back(std::move(r));
  }
  return runs;
}

}  // namespace

std::optional<FoundRunsDir> find_runs_dir_nearby(const fs::path& runs_dir) {
  if (runs_dir != "runs" || fs::exists(Catalogue::default_path(runs_dir))) return std::nullopt;
  std::vector<fs::path> found;
  size_t budget = 20000;
  catalogues_below(".", 3, budget, found);
  if (found.empty()) return std::nullopt;
  std::sort(found.begin(), found.end(), [](const fs::path& a, const fs::path& b) { return written(a) > written(b); });
  for (auto& f : found) f = f.lexically_normal();
  return FoundRunsDir{found.front(), {found.begin() + 1, found.end()}};
}

void note_found_runs_dir(const fs::path& runs_dir, const FoundRunsDir& found) {
  std::vector<std::string> names;
  for (const fs::path& o : found.others) names.push_back(Catalogue::default_path(o).string());
  const std::string others = names.empty() ? "" : fmt::format(" (the most recent; also {})", fmt::join(names, ", "));
  print_note(fmt::format("no catalogue at {}; reading {}{}; give --runs-dir to choose",
                         Catalogue::default_path(runs_dir).string(), Catalogue::default_path(found.dir).string(), others));
}

std::optional<fs::path> find_run_in(const std::string& ref, const fs::path& runs_dir) {
  const std::vector<RunEntry> runs = runs_in(runs_dir);
  if (ref == "latest") {
    const auto last = std::max_element(runs.begin(), runs.end(), [](const RunEntry& a, const RunEntry& b) {
      return std::tie(a.started_utc, a.name) < std::tie(b.started_utc, b.name);
    });
    if (last == runs.end()) return std::nullopt;
    return last->dir;
  }
  for (const RunEntry& r : runs) {
    if (r.name == ref || r.id == ref) return r.dir;
  }
  std::vector<const RunEntry*> hits;
  for (const RunEntry& r : runs) {
    if (r.name.rfind(ref, 0) == 0 || r.id.rfind(ref, 0) == 0) hits.push_back(&r);
  }
  if (hits.empty()) return std::nullopt;
  if (hits.size() == 1) return hits.front()->dir;
  std::vector<std::string> names;
  for (const RunEntry* r : hits) names.push_back(r->id == r->name ? r->id : r->id + " (" + r->name + ")");
  std::sort(names.begin(), names.end());
  // A message, not a listing (`runs` lists them): the first ten.
  constexpr size_t kNamed = 10;
  const std::string more = names.size() > kNamed ? fmt::format(" and {} more", names.size() - kNamed) : "";
  names.resize(std::min(names.size(), kNamed));
  throw InputError(fmt::format("{}: ambiguous: the start of {} runs in {}: {}{}; give more of the id", ref, hits.size(),
                               runs_dir.string(), fmt::join(names, ", "), more));
}

}  // namespace fpss::cli
