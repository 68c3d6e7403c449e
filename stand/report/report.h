// report.html of a run folder: Table 1 summary, residuals against angle, residual map; offline, self-contained.
#pragma once
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "calib/reduction.h"
#include "calib/samples.h"
#include "stand/catalogue/catalogue.h"
#include "stand/report/run_summary.h"

namespace fpss {

// The residual of one change null <-> offset (differences method) or of one dwell (absolute).
struct ResidualPoint {
  int64_t step = 0;             // the offset dwell's step (absolute: the dwell's)
  bool null_first = true;       // the change from the null before the offset; false: from the null after
  bool absolute = false;        // a dwell of the absolute method
  double ref_pitch_arcsec = 0;  // where: the offset dwell's reference angles
  double ref_yaw_arcsec = 0;
  // Model change - reference change, both taken offset minus null (absolute: model - reference).
  double pitch_arcsec = 0;
  double yaw_arcsec = 0;
  bool pitch_moved = true;      // the pitch reference changed between the two dwells (> 1 arcsec)
  bool yaw_moved = true;

};

struct RunResiduals {
  std::string method = "differences";
  std::vector<ResidualPoint> points;
  AxisResidualStats pitch, yaw;  // every figure set when there are points
  size_t null_dwells = 0, offset_dwells = 0;
  OutlierSummary outliers;  // the frames the reduction left out of the dwells these residuals are of
};

// The residuals of `cal` on the reduced recording, counted the way the calibrator counts them
// (its pairing and per-axis rows), so the summary equals calibration.json's residuals block when
// `cal` is the calibrator's fit of the same reduction. `method`: "differences" or "absolute".
// Throws InputError for an unknown method, DataError for a recording the dwells cannot be read from.
RunResiduals compute_residuals(const Reduction& reduced, const CoefficientSet& cal,
                               const std::string& method = "differences");
// The same on a recording, reduced as `cal`'s fit was (reduction_options_of its outliers block).
RunResiduals compute_residuals(const SampleTable& samples, const CoefficientSet& cal,
                               const std::string& method = "differences");

// A further part of the page (the acceptance certificate, ...): `html` is trusted markup.
struct ReportSection {
  std::string id;     // anchor, [a-z0-9-]
  std::string title;
  std::string html;
};

struct ReportOptions {
  std::string gnuplot;  // program; empty: $FPSS_GNUPLOT, else "gnuplot"
  // The run's recording as the session holds it in memory (samples.csv's rows, exactly: numbers
  // are written shortest-round-trip); null: read samples.csv. A session and `accept` hand it over,
  // so a process reads its recording at most once.
  const SampleTable* recording = nullptr;
  std::vector<ReportSection> extra_sections;
  std::optional<RunVerdict> verdict;  // the banner at the top; empty: run_verdict of run.json
};

// Everything the page shows, for callers that already hold it in memory.
struct ReportInput {
  std::string title;
  std::optional<RunFile> run;  // run.json; empty when the folder has none
  std::string samples_origin;                     // file the samples came from
  size_t samples = 0;
  std::optional<int64_t> fit_last_step;  // the calibration saw steps 1..this; Table 1 counts those rows only
  CoefficientSet calibration;
  std::string calibration_origin;
  RunResiduals residuals;
};

// Loads <run_dir>/samples.csv (unless `recording` is given), calibration.json and (when present)
// run.json. InputError naming the file for anything missing or malformed.
ReportInput load_report_input(const std::filesystem::path& run_dir, const SampleTable* recording = nullptr);

// The page. Plots that gnuplot cannot draw are replaced by a note saying why; never throws for that.
std::string render_report(const ReportInput& in, const ReportOptions& opts = {});

// Writes <run_dir>/report.html atomically and returns its path.
std::filesystem::path write_report(const std::filesystem::path& run_dir, const ReportOptions& opts = {});

// Text made safe for HTML element content and attribute values.
std::string html_escape(const std::string& text);

}  // namespace fpss
