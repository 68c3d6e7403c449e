// Isolated frames far from their step: the one outlier rule the calibrator and the diagnosis share.
#pragma once
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

namespace fpss {

// The floor under the robust sigma for whole counts: the rounded noise, sqrt(1/12 + s^2) counts,
// s the count noise per frame (unknown: the rounding's own 1/sqrt(12)). With little noise the
// pooled MAD of whole counts is zero, and the rounding alone would flag ordinary 2-count
// excursions at 0.3 counts of noise.
inline double count_outlier_floor(std::optional<double> noise_counts) {
  const double s = noise_counts.value_or(0.0);
  return std::sqrt(1.0 / 12.0 + s * s);
}

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
  // the line through their two nearest neighbours' running medians, with a limit 1.5x as wide.
  int local_half_window = 0;
};

// The rule for a sensor's counts in a dwell (the one reduction, the live screen, calibrate_csv):
// each frame against the running median of 7 frames of its step (local_half_window 3), so that a
// settling decay inside a dwell is followed while an isolated spike is not; `floor_counts` under
// the robust sigma (count_outlier_floor).
inline constexpr int kCountLocalHalfWindow = 3;
inline OutlierRule count_outlier_rule(double floor_counts) {
  OutlierRule r;
  r.min_sigma = floor_counts;
  r.local_half_window = kCountLocalHalfWindow;
  return r;
}

// What one frame of a step is judged against: the centre (NaN: not judged; a step too short for
// the rule) and whether it is a step's first or last frame under the local rule (judged against
// the line of its neighbours, 1.5x the limit).
struct FrameCentre {
  double centre = NAN;
  bool edge = false;
};

struct OutlierFlags {
  std::vector<bool> outlier;  // per frame
  int64_t count = 0;
  double robust_sigma = 0;    // in the residual's units
  std::vector<int64_t> steps; // ids of the steps that hold outliers, ascending, each once
};

// `residual` is what should be constant within a step (a dwell's counts or angle, a slew's model
// residual); `step` the step id of each frame, rows of one step contiguous or not.
//
// `shared_reading` (empty: every frame its own) says which frames took their residual against the
// reference reading of the frame before them in their step (same_reading, calib/samples.h).
// Frames that share one agree with their running median to the sensor's noise alone, without the
// reference's, and would shrink a sigma pooled from those deviations: with `shared_reading`, sigma
// is 1.4826 x the median of |difference| / sqrt(2) between neighbouring frames of a step on
// different readings (two independent draws of all the noise). Every frame is judged as without it.
OutlierFlags flag_outliers(const std::vector<double>& residual, const std::vector<int64_t>& step,
                           const OutlierRule& rule = {}, const std::vector<bool>& shared_reading = {});

// One step's frames (finite values, in frame order) under `rule`: each frame's centre, and the
// deviations the rule pools for its robust sigma (appended to `pooled`: |frame - step median|, or
// |frame - local median| / the window's Gaussian factor for interior frames under the local rule).
// flag_outliers and StepOutlierScreen both judge a step through this, so they are one rule.
std::vector<FrameCentre> step_centres(const std::vector<double>& frames, const OutlierRule& rule,
                                      std::vector<double>* pooled = nullptr);

// One step's frames judged by `rule` at the robust sigma: the frames farther than the limit from
// their centre. Under the local rule the worst is taken first and replaced by the line between its
// neighbours before the step is judged again, so that a spike's displacement of its neighbours'
// running median (one frame's decay in a settling dwell) does not make them outliers too.
std::vector<bool> judge_step(const std::vector<double>& frames, const OutlierRule& rule, double robust_sigma);

// One step's values as a multiset (value -> frames): the step's median without holding its frames
// (a handful of distinct values for whole counts, whatever the frames per step).
struct StepValues {
  std::map<double, uint64_t> values;
  uint64_t frames = 0;
  void add(double v) {
    if (std::isfinite(v)) {
      ++values[v];
      ++frames;
    }
  }
  // flag_outliers' median (the mean of the two middle values for an even count).
  double median() const;
};

// The same rule over a recording read step by step, in memory that does not grow with the frames
// (pooled deviations as a multiset: a handful of distinct values for whole counts): pass 1 pools
// every step's deviations (pool_step); after it, judge() gives a step's outlier frames at the
// pooled sigma, as flag_outliers judges them. Gives flag_outliers' flags exactly.
class StepOutlierScreen {
 public:
  explicit StepOutlierScreen(OutlierRule rule = {}) : rule_(rule) {}
  // `frames`: one step's values in frame order.
  void pool_step(const std::vector<double>& frames);
  // max(1.4826 x the pooled median absolute deviation, rule.min_sigma); 0 with nothing pooled.
  double robust_sigma() const;
  // The step's outlier frames at the sigma pooled so far (judge_step).
  std::vector<bool> judge(const std::vector<double>& frames) const { return judge_step(frames, rule_, robust_sigma()); }
  void set_min_sigma(double s) { rule_.min_sigma = s; }

 private:
  OutlierRule rule_;
  StepValues deviations_;
};

}  // namespace fpss
