// The paper's recursive least squares as a streaming estimator: one null/offset change at a time,
// a current estimate after each, and at the end the same refinement as the batch fit.
#pragma once
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "calib/calibrator.h"
#include "calib/outliers.h"

namespace fpss {

// Information-form recursive least squares: each change is a rank-one update of the frequency
// grid's Gram matrix (fit::FrequencyGram), which is the exact recursive LS of every grid node at
// once; current() picks the best node. Each change is also kept as one small record (counts at
// null and offset, reference change), on which finish() runs the batch fit's refinement, so the
// two agree on the same data.
class StreamingCalibrator {
 public:
  // Differences method only (the paper's); throws std::invalid_argument otherwise.
  explicit StreamingCalibrator(CalibrationOptions opts = {}, std::string source = "stream");

  // Rows as they are recorded; a dwell enters when the next step starts (or at finish()). With
  // opts.reject_outliers, a step's frames are judged when it ends by the one outlier rule
  // (calib/outliers.h): against the running median of 7 frames of the step (a settling decay is
  // followed, a spike is not), with the robust sigma pooled over the steps so far (floor: the rounded count noise when known, else the rounding's), so a glitch frame stays
  // out of the live estimate as it stays out of the batch fit.
  void add_sample(const Sample& s);
  // A whole dwell: an offset pairs with the last null, a null with the offsets since the last null.
  void add_dwell(const Dwell& d);
  // One change directly: the null dwell and the offset dwell it was measured against.
  void add_pair(const Dwell& null_dwell, const Dwell& offset_dwell);
  // Counts the null dwell's null condition (C1); add_dwell does this itself.
  void add_null(const Dwell& null_dwell);

  size_t pairs() const { return pitch_.rows(); }
  // Rows counted in the report's `samples` when dwells (not rows) are fed, e.g. by calibrate_csv.
  void set_samples(size_t n) { samples_ = n; }

  struct Estimate {
    bool valid = false;
    std::string why_not;  // when not valid: what the data cannot tell yet
    size_t pairs = 0;
    AxisCoeffs alpha{}, beta{};  // best grid node, linear parameters exact, C1 by the null condition
    double rms_pitch_arcsec = 0, rms_yaw_arcsec = 0;  // residual RMS over the changes so far
  };
  // Cheap (a few thousand 6x6 solves): meant to be called after every change.
  Estimate current() const;

  // The full fit of everything added so far (the batch fit's refinement and report).
  CalibrationReport finish();
  // The same fit of the dwells completed so far, leaving the calibrator as it was: what an honest
  // uncertainty mid-run comes from (its angle sigmas over `opts.sigma_range_*`, when given).
  // Costs a batch fit of the changes so far (milliseconds for a grid of a few hundred).
  CalibrationReport fit_so_far(const CalibrationOptions& opts) const;
  // One axis of it (DataError when the changes so far cannot tell that axis's coefficients).
  AxisFit fit_so_far(fit::Axis axis, const CalibrationOptions& opts) const;
  const CalibrationOptions& options() const { return opts_; }

 private:
  void take_dwell(const Dwell& d);
  void close_step();  // the held step's rows, judged, into the builder and its dwell taken

  CalibrationOptions opts_;
  std::string source_;
  DwellBuilder builder_;
  std::vector<Sample> step_rows_;   // the dwell step under way (outliers judged when it ends)
  StepOutlierScreen screen_[2];     // alpha, beta
  DwellPairer pairer_;
  std::vector<Dwell> recent_;  // dwells the pairer may still refer to, by index
  size_t first_recent_ = 0;  // pairer index of recent_[0]
  size_t samples_ = 0, null_dwells_ = 0, offset_dwells_ = 0;
  OutlierSummary outliers_;
  fit::AxisData pitch_, yaw_;
  fit::FrequencyGram gram_pitch_, gram_yaw_;
};

// calibrate() of a samples file without holding it: the file is read row by row (three passes when
// outliers are screened and the count noise is not given: the pooled robust sigma, the noise from
// the within-dwell scatter for the outlier floor, then the dwells), one step's rows, the pooled
// deviations and dwell sums are kept, and the dwells go to the StreamingCalibrator. The same
// outlier rule, dwells and fit as calibrate(read_samples_csv(path)). The absolute method has no
// streaming form: it reads the file whole.
CalibrationReport calibrate_csv(const std::filesystem::path& path, const CalibrationOptions& opts = {});

}  // namespace fpss
