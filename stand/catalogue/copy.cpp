// Copying one catalogue into another, idempotently (records known by their content, not their ids).
#include "stand/catalogue/copy.h"

#include <algorithm>
#include <set>
#include <tuple>

namespace fpss {

CopyReport copy_catalogue(const Catalogue& from, Catalogue& to) {
  CopyReport r;
  const auto units = from.units();
  for (const auto& u : units) r.units_added += to.add_unit(u) ? 1 : 0;
  auto runs = from.list_runs();
  std::reverse(runs.begin(), runs.end());  // oldest first, as they were made
  for (const auto& run : runs) {
    ++r.runs_seen;
    r.runs_added += to.copy_run(run) ? 1 : 0;
  }
  for (const auto& u : units) {
    std::set<std::pair<std::string, std::string>> have;  // (run id or "import:" date, coefficients)
    for (const auto& c : to.unit_history(u)) {
      have.emplace(c.run_id ? *c.run_id : "import:" + c.date_utc, c.coefficients.dump());
    }
    for (const auto& c : from.unit_history(u)) {
      ++r.calibrations_seen;
      const auto key = std::make_pair(c.run_id ? *c.run_id : "import:" + c.date_utc, c.coefficients.dump());
      if (have.count(key)) continue;
      if (c.source == "import" && !c.date_utc.empty()) r.calibrations_added += to.record_import_once(c).second ? 1 : 0;
      else {
        to.record_calibration(c);
        ++r.calibrations_added;
      }
      have.insert(key);
    }
    std::set<std::tuple<std::string, std::string, bool>> accepted;
    for (const auto& a : to.unit_acceptances(u)) accepted.emplace(a.run_id.value_or(""), a.date_utc, a.passed);
    for (const auto& a : from.unit_acceptances(u)) {
      ++r.acceptances_seen;
      if (!accepted.emplace(a.run_id.value_or(""), a.date_utc, a.passed).second) continue;
      to.record_acceptance(a);
      ++r.acceptances_added;
    }
  }
  return r;
}

}  // namespace fpss
