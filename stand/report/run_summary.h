// What a run folder says about its run, read without changing it: the verdict (the report's
// banner), the live progress, and the summary `fpss-stand show` and `runs` print.
#pragma once
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "calib/samples.h"
#include "stand/catalogue/catalogue.h"
#include "stand/catalogue/run_file.h"

namespace fpss {

// A run's verdict: an acceptance's when the run was one (run.json "acceptance".verdict), else
// the run's own: "pass" when it completed (every check step held), "fail" when a check or the
// calibration failed, "running" while it runs, "incomplete" when it stopped before a verdict.
struct RunVerdict {
  std::string verdict;  // pass | conditional | fail | running | incomplete
  std::string why;      // one sentence for people (the stop reason, the failed limits)
};
// Several units (run.json `units`): every unit passes, or the worst unit verdict, naming each unit.
RunVerdict run_verdict(const RunFile& run);
// One unit of several: lost (fail, naming the loss), its acceptance's, else how the run ended.
RunVerdict unit_verdict(const RunFile& run, const RunFileUnit& unit);
// A folder without run.json: "incomplete", the run's end unknown.
RunVerdict run_verdict(const std::optional<RunFile>& run);

// The banner at the top of report.html: PASS / FAIL / RUNNING / INCOMPLETE in a coloured box.
// `id`: the element's id (a page of several units has one banner per unit).
std::string verdict_banner_html(const RunVerdict& v, const std::string& id = "verdict");

// The last step a calibration was fitted on (calibration.json "fit_last_step", written by the run);
// empty for a calibration that does not say. InputError naming `origin` for a wrong value.
std::optional<int64_t> fit_last_step(const CoefficientSet& cal, const std::string& origin);

struct RunSummary {
  std::filesystem::path dir;
  std::string run_id, unit, procedure, outcome, stop_cause, reason, started_utc, ended_utc;
  bool emulated = false;
  int64_t points_total = 0, points_done = 0;  // done: the journal's lines, so live while it runs
  RunVerdict verdict;
  std::string calibration;                    // file name in the folder, "" for none
  std::optional<AxisResidualStats> pitch, yaw;  // the calibration's residuals (Table 1 form)
  std::vector<std::string> files;             // what the folder holds, by name
  // The run's diagnosis (run.json files.gap, GAP.json), when it has one with a verdict: a run that
  // completed and passed its checks may still show a sim-to-real gap, and the summary says so.
  struct Diagnosis {
    std::string file, verdict, sentence, cause;  // verdict: no_gap | explained | partly_explained | unexplained
    std::vector<std::string> causes;             // every cause's name, the first is `cause`
  };
  std::optional<Diagnosis> diagnosis;
  // Several units: each one's outcome, verdict, calibration and pose relative to the first.
  struct Unit {
    RunFileUnit unit;
    RunVerdict verdict;
  };
  std::vector<Unit> units;

  nlohmann::ordered_json to_json() const;
  std::string text() const;  // the lines `fpss-stand show` prints
};

// Reads run.json, points.jsonl, the calibration's residuals block and GAP.json's verdict; InputError naming the file
// for a folder that is not a run folder or a file that does not parse.
RunSummary read_run_summary(const std::filesystem::path& run_dir);

// Completed points in <run_dir>/points.jsonl (whole lines), 0 when there is none.
int64_t journal_points(const std::filesystem::path& run_dir);

}  // namespace fpss
