// Records the catalogue tests share: a run start of the discrete grid, emulated; and the work of one
// of several writers racing on one catalogue.
#pragma once
#include <cstdio>
#include <random>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "stand/catalogue/catalogue.h"

namespace fpss::test {

inline RunStart make_run(const std::string& id, const std::string& unit, const std::string& started = "",
                         const std::string& stand = "") {
  RunStart r;
  r.run_id = id;
  r.unit = unit;
  r.procedure = "discrete_grid";
  r.procedure_hash = "sha256:0123abcd";
  r.started_utc = started;
  r.run_dir = "runs/" + id;
  r.emulated = true;
  r.stand = stand;
  return r;
}

// Writer w's i-th run; writer_of_run reads w and i back (false for another id).
inline std::string writer_run_id(int w, int i) { return fmt::format("w{}-run{:04}", w, i); }
inline bool writer_of_run(const std::string& run_id, int& w, int& i) {
  return std::sscanf(run_id.c_str(), "w%d-run%d", &w, &i) == 2;
}
// The pitch mean of writer w's i-th calibration: a row mixed with another writer's would show.
inline double writer_pitch_mean(int w, int i) { return 0.1 * w + 0.001 * i; }

// Writer w's share of a race: `runs` runs, each started, calibrated (calibration(unit, pitch mean)
// gives its calibration.json) and ended in its own transactions, on units drawn from `units`
// serials so writers contend for them.
template <typename MakeRun, typename Calibration>
void write_runs(Catalogue& cat, int w, int runs, int units, unsigned seed, MakeRun make_run,
                Calibration calibration) {
  std::mt19937 rng(seed + static_cast<unsigned>(w));
  for (int i = 0; i < runs; ++i) {
    const std::string unit = fmt::format("SN-{}", rng() % static_cast<unsigned>(units));
    const std::string id = writer_run_id(w, i);
    cat.record_run_start(make_run(id, unit));
    auto cal = CalibrationRecord::from_calibration_json(calibration(unit, writer_pitch_mean(w, i)), id);
    cal.run_id = id;
    cat.record_calibration(cal);
    cat.record_run_end(id, RunOutcome::completed);
  }
}

}  // namespace fpss::test
