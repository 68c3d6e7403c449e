// Isolated frames far from their step: the one outlier rule the calibrator and the diagnosis share.
#pragma once
#include <cstdint>
#include <vector>

namespace fpss {

struct OutlierRule {
  // A frame is an outlier when it lies more than `threshold_sigma` robust sigmas from its step's
  // median. Sigma is 1.4826 x the median absolute deviation of every frame from its step's median,
  // pooled over the recording (so one step of a few frames cannot hide its own spike).
  double threshold_sigma = 6.0;
  // Steps with fewer frames than this have no robust median of their own and are never flagged.
  int min_step_frames = 3;
  // Floor under the robust sigma, in the residual's units: whole-count data with little noise has a
  // median absolute deviation of zero, so the caller passes the rounding's own scatter (1/sqrt(12)
  // of a count, in the residual's units) or the expected noise.
  double min_sigma = 0;
  // 0: the centre is the step's median (a step at rest). k > 0: the centre is the median of the
  // frame and its neighbours within the same step (in frame order), up to k on each side and as
  // many on both sides: it follows a step change, a settling decay or a slew's changing residual,
  // while an isolated spike is never the median. A step's first and last frames are judged against
  // the line through their nearest neighbours, with a limit 1.5x as wide.
  int local_half_window = 0;
};

struct OutlierFlags {
  std::vector<bool> outlier;  // per frame
  int64_t count = 0;
  double robust_sigma = 0;    // in the residual's units
  std::vector<int64_t> steps; // ids of the steps that hold outliers, ascending, each once
};

// `residual` is what should be constant within a step (a dwell's counts or angle, a slew's model
// residual); `step` the step id of each frame, rows of one step contiguous or not.
OutlierFlags flag_outliers(const std::vector<double>& residual, const std::vector<int64_t>& step,
                           const OutlierRule& rule = {});

}  // namespace fpss
