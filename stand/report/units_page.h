// The report of a run with several units on one gimbal: a section and a verdict banner per unit, and how the units sit relative to the first.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "stand/catalogue/run_file.h"
#include "stand/report/run_summary.h"

namespace fpss {

// One unit's verdict: lost (fail, naming the loss), its acceptance's, else the run's.
RunVerdict unit_verdict(const RunFile& run, const RunFileUnit& unit);

struct UnitReport {
  RunFileUnit unit;
  RunVerdict verdict;
  std::optional<std::filesystem::path> report;  // its own report.html (units/<SERIAL>/report.html)
};

// RUN_DIR/report.html: the run's banner (every unit's outcome), then per unit its banner, its
// outcome and files, its Table 1 from its calibration.json, and its boresight and roll relative
// to the first unit. Written atomically; returns its path.
std::filesystem::path write_units_report(const std::filesystem::path& run_dir, const RunFile& run,
                                         const std::vector<UnitReport>& units);

}  // namespace fpss
