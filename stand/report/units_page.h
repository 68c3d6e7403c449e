// The report of a run with several units on one gimbal: a section and a verdict banner per unit, and how the units sit relative to the first.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "calib/samples.h"
#include "stand/catalogue/run_file.h"
#include "stand/report/run_summary.h"

namespace fpss {

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

// What a unit's own report is drawn from: its folder (calibration.json inside) and its recording.
struct UnitFolder {
  std::filesystem::path dir;
  const SampleTable* recording = nullptr;  // null: its samples.csv is read
};
// Each unit's own report (units/<SERIAL>/report.html, where it has a calibration, its banner its
// unit_verdict), then the run's page (write_units_report). `units` in run.json's units order.
std::filesystem::path write_unit_reports(const std::filesystem::path& run_dir, const RunFile& run,
                                         const std::vector<UnitFolder>& units);

}  // namespace fpss
