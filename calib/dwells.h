// Dwell averaging and null/offset pairing: the samples a calibration fits, reduced to one record per dwell.
#pragma once
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "calib/samples.h"

namespace fpss {

// Which axes' counts the outlier rule rejected in one frame (calib/reduction.h). A frame rejected
// on either axis stays out of both axes' means (a glitch corrupts the frame, not one number).
struct OutlierAxes {
  bool alpha = false, beta = false;
  bool any() const { return alpha || beta; }
};

// The mean of the null/offset rows of one step. Scatter is the sample standard deviation
// (0 for a single sample): it tells how well the mean is known, not how good the fit is.
struct Dwell {
  int64_t step = 0;
  Phase phase = Phase::null;  // null or offset, never slew/move
  size_t samples = 0;
  double t_start_s = 0, t_end_s = 0;
  double counts_alpha = 0, counts_beta = 0;
  double ref_pitch_arcsec = 0, ref_yaw_arcsec = 0;
  double sd_counts_alpha = 0, sd_counts_beta = 0;
  // The counts' scatter about a straight line in time (n - 2 degrees of freedom; the plain scatter
  // below 3 frames): the noise at rest with a slow drift through the dwell removed (jitter).
  double sd_detrended_counts_alpha = 0, sd_detrended_counts_beta = 0;
  // The reference's scatter over the dwell's encoder readings (not its frames: frames that share
  // one reading repeat its value, calib/dwells.cpp) and how many independent readings its mean is
  // worth, n^2 / sum of m^2 over readings shared by m frames: `samples` when each frame has its own.
  double sd_ref_pitch_arcsec = 0, sd_ref_yaw_arcsec = 0;
  size_t ref_readings = 0;          // distinct readings
  double ref_readings_eff = 0;      // the mean's worth in independent readings
  // Every frame's counts were whole numbers (the sensor's own output, not averaged upstream):
  // the quantisation correction applies.
  bool whole_counts_alpha = true, whole_counts_beta = true;
  size_t outliers = 0;  // frames left out of the means (calib/outliers.h): rejected on either axis
  size_t outliers_alpha = 0, outliers_beta = 0;  // ... rejected on that axis's counts
  // The sensor's mean temperature over the step's rows, C (samples.csv `temperature_c`, its
  // finite values); NaN when the recording has none.
  double temperature_c = std::numeric_limits<double>::quiet_NaN();
  size_t frames() const { return samples + outliers; }  // every frame of the step
};

// One change the differences method fits: from the null dwell to the offset dwell
// (null_first) or back from the offset to the next null.
struct DwellPair {
  size_t null_index = 0, offset_index = 0;  // into the dwell list the pairer was fed
  bool null_first = true;
};

// Folds rows into dwells one at a time, so live recording and batch files share one path.
// Rows of phase slew/move are ignored; a step holding both null and offset rows is a DataError.
class DwellBuilder {
 public:
  explicit DwellBuilder(std::string origin = {}) : origin_(std::move(origin)) {}
  // Returns the dwell that the previous step completed, when this row starts a new one.
  // A row rejected on either axis opens and closes steps like any other but stays out of the
  // dwell's means (counted in Dwell::outliers and per axis).
  // `temperature_c`: the row's sensor temperature (NaN: none); the dwell's is the mean of its
  // rows' finite ones, outliers included (a glitch corrupts counts, not the temperature reading).
  std::optional<Dwell> add(const Sample& s, OutlierAxes outlier = {},
                           double temperature_c = std::numeric_limits<double>::quiet_NaN());
  // The dwell still open (end of data).
  std::optional<Dwell> flush();

 private:
  struct Sums {
    double n = 0, t0 = 0, t1 = 0;
    // Shifted sums (first value as origin) keep the variance exact for large counts: counts and
    // references over frames (the means), the references again over readings (their scatter).
    double o[4] = {0, 0, 0, 0}, s[4] = {0, 0, 0, 0}, ss[4] = {0, 0, 0, 0};
    double rs[2] = {0, 0}, rss[2] = {0, 0};
    double st = 0, stt = 0, stv[2] = {0, 0};  // time (from t0) against the counts: the detrended scatter
    double readings = 0, run = 0, run_ss = 0;  // readings, frames on the current one, sum of runs^2
    double last_ref[2] = {0, 0};
    bool whole[2] = {true, true};
    size_t skipped = 0, skipped_axis[2] = {0, 0};
    bool origin_set = false;
    double temp_sum = 0, temp_n = 0;
  };
  void add_reference(const double* ref);
  std::optional<Dwell> close();
  double detrended_sd(int axis, double plain_sd) const;
  std::string origin_;
  bool open_ = false;
  int64_t step_ = 0;
  Phase phase_ = Phase::null;
  Sums sums_;
};

// Pairs each offset dwell with the nearest null dwell before it and the nearest after it.
class DwellPairer {
 public:
  // Index of `d` in the caller's dwell list is the number of dwells added before it.
  // Returns the pairs this dwell completes.
  std::vector<DwellPair> add(const Dwell& d);

 private:
  size_t count_ = 0;
  std::optional<size_t> last_null_;
  std::vector<size_t> waiting_offsets_;  // offsets since the last null, paired when the next null comes
};

// Every row kept (no outlier rule); calib/reduction.h's reduce() is the recording's reduction.
std::vector<Dwell> average_dwells(const SampleTable& t);
// The same, leaving out the rows flagged in `skip` (one entry per row; each dwell counts its own).
std::vector<Dwell> average_dwells(const SampleTable& t, const std::vector<OutlierAxes>& skip);
std::vector<Dwell> average_dwells(const FrameColumns& f, const std::vector<OutlierAxes>& skip);
std::vector<DwellPair> pair_dwells(const std::vector<Dwell>& dwells);

}  // namespace fpss
