#include "stand/console/fleet.h"

#include <algorithm>
#include <map>
#include <system_error>

#include "base/json_file.h"
#include "base/text_file.h"
#include "stand/catalogue/catalogue.h"
#include "stand/console/run_files.h"

namespace fpss::console {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr size_t kMaxRuns = 5000, kMaxUnits = 1000;
constexpr size_t kMaxMsaBytes = 8 * 1024 * 1024;

json stands_json(const Catalogue& cat) {
  std::map<std::string, json> last;  // runs come most recent first: the first of each stand
  for (const RunRecord& r : cat.list_runs({.unit = std::nullopt, .limit = kMaxRuns})) {
    const std::string stand = r.stand.empty() ? "emulated" : r.stand;
    if (last.count(stand)) continue;
    last[stand] = {{"stand", stand},
                   {"run_id", r.run_id},
                   {"unit", r.unit},
                   {"procedure", r.procedure},
                   {"started_utc", r.started_utc},
                   {"outcome", r.stale() ? "stale" : r.outcome_name()},
                   {"live", r.running() && !r.stale()},
                   {"host", r.host}};
  }
  json out = json::array();
  for (auto& [k, v] : last) out.push_back(std::move(v));
  return out;
}

json units_json(const Catalogue& cat) {
  json out = json::array();
  std::vector<std::string> units = cat.units();
  if (units.size() > kMaxUnits) units.resize(kMaxUnits);
  for (const std::string& u : units) {
    const auto acc = cat.unit_acceptances(u);
    const auto latest = std::max_element(acc.begin(), acc.end(), [](const AcceptanceRecord& a, const AcceptanceRecord& b) {
      return a.date_utc < b.date_utc;
    });
    if (latest == acc.end()) {
      out.push_back({{"unit", u}, {"verdict", nullptr}, {"date_utc", nullptr}, {"stand", nullptr}});
      continue;
    }
    const std::string verdict = latest->certificate.is_object() && latest->certificate.contains("verdict") &&
                                        latest->certificate["verdict"].is_string()
                                    ? latest->certificate["verdict"].get<std::string>()
                                    : (latest->passed ? "pass" : "fail");
    out.push_back({{"unit", u}, {"verdict", verdict}, {"date_utc", latest->date_utc},
                   {"stand", latest->stand.empty() ? "emulated" : latest->stand}});
  }
  return out;
}

// The newest readable `fpss-stand msa/1` file of RUNS_DIR/msa/, in brief; null without one.
json last_msa(const fs::path& runs_dir) {
  std::error_code ec;
  std::vector<std::pair<fs::file_time_type, fs::path>> files;
  for (const auto& e : fs::directory_iterator(runs_dir / "msa", ec)) {
    if (e.path().extension() == ".json" && e.is_regular_file(ec) && !e.is_symlink(ec)) {
      files.emplace_back(e.last_write_time(ec), e.path());
    }
  }
  std::sort(files.rbegin(), files.rend());
  for (const auto& [t, path] : files) {
    try {
      const json m = parse_json_text(read_text_file(path, "MSA file", kMaxMsaBytes), path.string());
      if (!m.is_object() || m.value("format", "") != "fpss-stand msa/1" || !m["quantities"].is_object()) continue;
      json q = json::array();
      for (const auto& [name, v] : m["quantities"].items()) {
        q.push_back({{"name", name}, {"grr_percent_tolerance", v.value("grr_percent_tolerance", json())},
                     {"grr_percent_tv", v.value("grr_percent_tv", json())}, {"ndc", v.value("ndc", json())},
                     {"verdict", v.value("verdict", json())}});
      }
      return {{"file", path.filename().string()}, {"units", m.value("units", json::array())},
              {"stands", m.value("stands", json::array())}, {"repeats", m.value("repeats", json())},
              {"quantities", q}};
    } catch (const std::exception&) {
      // an unreadable or foreign file: the next older one
    }
  }
  return nullptr;
}

}  // namespace

json fleet_json(CataloguePool& catalogue) {
  json out{{"stands", json::array()}, {"units", json::array()}, {"msa", last_msa(catalogue.runs_dir())}};
  const auto cat = catalogue.acquire();
  if (!cat) return out;
  out["stands"] = stands_json(*cat);
  out["units"] = units_json(*cat);
  return out;
}

}  // namespace fpss::console
