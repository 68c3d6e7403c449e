// The one reduction of a recording: frames to dwells by one outlier rule; every figure starts here.
#pragma once
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/dwells.h"
#include "calib/quantisation.h"
#include "calib/samples.h"

namespace fpss {

// How the count outlier rule (calib/outliers.h) is set: with the count noise known, its floor is
// the rounded noise sqrt(1/12 + s^2); unknown, s is estimated from the within-dwell scatter of a
// first pass that keeps gross spikes out of it.
struct ReductionOptions {
  bool reject_outliers = true;
  std::optional<double> count_noise_counts;  // per frame, before rounding
  std::string count_noise_source = "caller";
};

// Frames the rule rejected, per axis and in all: a glitching unit is a finding, not noise.
struct OutlierCount {
  size_t outlier_frames = 0;
  double share(size_t frames) const { return frames ? static_cast<double>(outlier_frames) / static_cast<double>(frames) : 0.0; }
};
struct OutlierSummary {
  size_t frames = 0;                // frames of null/offset dwells
  OutlierCount any, alpha, beta;    // rejected on either axis (left out of both means), on alpha, on beta
  bool applied = true;              // the rule ran (false: every frame kept)
  std::optional<double> count_noise_counts;  // the count noise under the rule's floor, given or estimated
  std::string count_noise_source;            // "caller", "stand file", "within-dwell scatter", "unknown"

  void add(const Dwell& d);
  // The largest share of the two axes (the acceptance criterion's measure).
  double worst_share() const;
  // {"frames", "outlier_frames", "share", "pitch": {"outlier_frames", "share"}, "yaw": {...},
  //  "rule": {"applied", "threshold_sigma", "count_noise_counts", "count_noise_source"}}
  nlohmann::json to_json() const;
  // InputError naming `origin` for a block that is not of that form.
  static OutlierSummary from_json(const nlohmann::json& j, const std::string& origin);
  // The options that redo the same reduction of the same rows (the rule's noise as it was used).
  ReductionOptions options() const;
};

struct Reduction {
  std::vector<Dwell> dwells;             // in recording order
  std::vector<OutlierAxes> flags;        // per row of the table (empty: nothing flagged)
  OutlierSummary outliers;
};

// The reduction a calibration file's fit was made on (its "outliers" block's rule), so that a
// report or a judge redoes the same one; a file without the block (imported, older): the default.
ReductionOptions reduction_options_of(const nlohmann::json& calibration_extra, const std::string& origin);

// Null and offset rows become dwells here and nowhere else: the calibrator, the report's Table 1,
// acceptance's accuracy and jitter and the outlier counts all read this result.
Reduction reduce(const SampleTable& t, const ReductionOptions& opts = {});
// The same on borrowed columns (the diagnosis's recording, which holds no SampleTable).
Reduction reduce(const FrameColumns& f, const ReductionOptions& opts = {});

// A dwell's evidence of the count noise: its two axes' within-dwell scatter, when it has at least
// two frames of whole counts (the sensor's own output); false otherwise.
bool count_scatters(const Dwell& d, CountScatter out[2]);

// Per row, the axes whose counts the rule rejects with this floor under the robust sigma.
std::vector<OutlierAxes> flag_count_outliers(const FrameColumns& f, double floor_counts);

}  // namespace fpss
