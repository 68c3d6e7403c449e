#include "calib/streaming.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <stdexcept>
#include <unordered_map>
#include <utility>
#include <vector>

#include "base/errors.h"
#include "calib/outliers.h"
#include "calib/quantisation.h"
#include "calib/reference_fit.h"
#include "calib/refine.h"

namespace fpss {

StreamingCalibrator::StreamingCalibrator(CalibrationOptions opts, std::string source)
    : opts_(std::move(opts)),
      source_(std::move(source)),
      builder_(source_),
      gram_pitch_(opts_.grid, true),
      gram_yaw_(opts_.grid, true) {
  if (opts_.method != Method::differences) {
    throw std::invalid_argument("the streaming calibrator fits changes (method differences) only");
  }
  pitch_.differences = yaw_.differences = true;
  for (auto& sc : screen_) sc = StepOutlierScreen(count_outlier_rule(count_outlier_floor(opts_.count_noise_counts)));
}

void StreamingCalibrator::add_sample(const Sample& s) {
  ++samples_;
  const bool dwell = s.phase == Phase::null || s.phase == Phase::offset;
  if (!step_rows_.empty() && (!dwell || s.step != step_rows_.back().step)) close_step();
  if (dwell) step_rows_.push_back(s);
}

void StreamingCalibrator::close_step() {
  if (step_rows_.empty()) return;
  std::vector<double> v[2];
  for (const Sample& r : step_rows_) {
    v[0].push_back(r.counts_alpha);
    v[1].push_back(r.counts_beta);
  }
  screen_[0].pool_step(v[0]);
  screen_[1].pool_step(v[1]);
  const std::vector<bool> f[2] = {screen_[0].judge(v[0]), screen_[1].judge(v[1])};
  for (size_t q = 0; q < step_rows_.size(); ++q) {
    OutlierAxes o;
    if (opts_.reject_outliers) o = {f[0][q], f[1][q]};
    if (auto d = builder_.add(step_rows_[q], o)) take_dwell(*d);
  }
  step_rows_.clear();
  if (auto d = builder_.flush()) take_dwell(*d);
}

void StreamingCalibrator::add_dwell(const Dwell& d) {
  if (d.phase != Phase::null && d.phase != Phase::offset) return;
  take_dwell(d);
}

void StreamingCalibrator::take_dwell(const Dwell& d) {
  const size_t index = first_recent_ + recent_.size();
  if (d.phase == Phase::offset) ++offset_dwells_;
  outliers_.add(d);
  recent_.push_back(d);
  for (const auto& p : pairer_.add(d)) {
    add_pair(recent_[p.null_index - first_recent_], recent_[p.offset_index - first_recent_]);
  }
  if (d.phase == Phase::null) {
    add_null(d);
    // Only the last null and the offsets after it can still be paired.
    recent_.assign(1, d);
    first_recent_ = index;
  }
}

void StreamingCalibrator::add_pair(const Dwell& null_dwell, const Dwell& offset_dwell) {
  fit::add_pair_rows(pitch_, fit::Axis::alpha, null_dwell, offset_dwell);
  fit::add_pair_rows(yaw_, fit::Axis::beta, null_dwell, offset_dwell);
  const size_t p = pitch_.rows() - 1, y = yaw_.rows() - 1;
  gram_pitch_.add(pitch_.row_n_plus(p), pitch_.row_n_minus(p), pitch_.row_y_arcsec(p));
  gram_yaw_.add(yaw_.row_n_plus(y), yaw_.row_n_minus(y), yaw_.row_y_arcsec(y));
}

void StreamingCalibrator::add_null(const Dwell& null_dwell) {
  fit::add_null(pitch_, fit::Axis::alpha, null_dwell);
  fit::add_null(yaw_, fit::Axis::beta, null_dwell);
  ++null_dwells_;
}

StreamingCalibrator::Estimate StreamingCalibrator::current() const {
  Estimate e;
  e.pairs = pairs();
  try {
    fit::check_axis(pitch_, fit::Axis::alpha, source_);
    fit::check_axis(yaw_, fit::Axis::beta, source_);
  } catch (const DataError& err) {
    e.why_not = err.what();
    return e;
  }
  const auto np = gram_pitch_.best_nodes(1), ny = gram_yaw_.best_nodes(1);
  if (np.empty() || ny.empty()) {
    e.why_not = "no pair of grid frequencies gives a solvable linear problem yet";
    return e;
  }
  e.alpha = gram_pitch_.coefficients(np.front());
  e.beta = gram_yaw_.coefficients(ny.front());
  e.alpha[0] = fit::null_condition_c1(pitch_, e.alpha);
  e.beta[0] = fit::null_condition_c1(yaw_, e.beta);
  e.rms_pitch_arcsec = std::sqrt(np.front().cost / static_cast<double>(gram_pitch_.rows()));
  e.rms_yaw_arcsec = std::sqrt(ny.front().cost / static_cast<double>(gram_yaw_.rows()));
  e.valid = true;
  return e;
}

CalibrationReport StreamingCalibrator::finish() {
  close_step();
  if (auto d = builder_.flush()) take_dwell(*d);
  CalibrationReport rep = fit_so_far(opts_);
  add_reference_uncertainty(rep, opts_);  // the final fit only: the live one answers for the data
  return rep;
}

CalibrationReport StreamingCalibrator::fit_so_far(const CalibrationOptions& opts) const {
  CalibrationReport rep;
  rep.method = Method::differences;
  rep.source = source_;
  rep.unit = opts.unit.empty() && opts.init ? opts.init->unit : opts.unit;
  rep.samples = samples_;
  rep.null_dwells = null_dwells_;
  rep.offset_dwells = offset_dwells_;
  rep.pairs = pairs();
  rep.outliers = outliers_;
  rep.outliers.applied = opts.reject_outliers;
  fit::check_axis(pitch_, fit::Axis::alpha, source_);
  fit::check_axis(yaw_, fit::Axis::beta, source_);
  rep.pitch = fit::fit_axis(pitch_, gram_pitch_, fit::Axis::alpha, opts);
  rep.yaw = fit::fit_axis(yaw_, gram_yaw_, fit::Axis::beta, opts);
  return rep;
}

AxisFit StreamingCalibrator::fit_so_far(fit::Axis axis, const CalibrationOptions& opts) const {
  const bool alpha = axis == fit::Axis::alpha;
  fit::check_axis(alpha ? pitch_ : yaw_, axis, source_);
  return fit::fit_axis(alpha ? pitch_ : yaw_, alpha ? gram_pitch_ : gram_yaw_, axis, opts);
}

namespace {

bool is_dwell_row(const Sample& s) { return s.phase == Phase::null || s.phase == Phase::offset; }

// The null/offset rows of a file, a step at a time (its rows in order; a step is short, so only
// one is held): on_step(rows, their temperatures, NaN where none). Returns the rows of the file.
using StepRows = std::function<void(const std::vector<Sample>&, const std::vector<double>&)>;
size_t each_dwell_step(const std::filesystem::path& path, const StepRows& on_step) {
  std::vector<Sample> rows;
  std::vector<double> temps;
  size_t n = 0;
  for_each_sample_chunk(path, [&](const SampleTable& chunk, size_t first_new, double) {
    const std::vector<double> temp =
        chunk.has_column("temperature_c") ? chunk.numeric_column("temperature_c") : std::vector<double>{};
    for (size_t i = first_new; i < chunk.size(); ++i, ++n) {
      const Sample s = chunk.row(i);
      if (!rows.empty() && (!is_dwell_row(s) || s.step != rows.back().step)) {
        on_step(rows, temps);
        rows.clear();
        temps.clear();
      }
      if (!is_dwell_row(s)) continue;
      rows.push_back(s);
      temps.push_back(temp.empty() ? std::numeric_limits<double>::quiet_NaN() : temp[i]);
    }
  });
  if (!rows.empty()) on_step(rows, temps);
  return n;
}

// The dwell steps of a file, pass after pass. A small file's steps are parsed once and kept, so its
// later passes cost no parsing (they were most of calibrate's time on a file of ~10,000 rows); a
// large file's are read again on every pass, so memory stays flat however long the recording.
class DwellSteps {
 public:
  // Files up to this size are kept: at ~40 bytes a row about 100,000 rows, 64 bytes each in memory.
  static constexpr uintmax_t kKeepBytes = 4u << 20;
  explicit DwellSteps(std::filesystem::path path) : path_(std::move(path)) {
    std::error_code ec;
    const uintmax_t bytes = std::filesystem::file_size(path_, ec);
    keep_ = !ec && bytes <= kKeepBytes;
  }
  // on_step for every step in order; returns the rows of the file.
  size_t each(const StepRows& on_step) {
    if (kept_) {
      for (const auto& [rows, temps] : steps_) on_step(rows, temps);
      return rows_;
    }
    steps_.clear();
    rows_ = each_dwell_step(path_, [&](const std::vector<Sample>& rows, const std::vector<double>& temps) {
      if (keep_) steps_.emplace_back(rows, temps);
      on_step(rows, temps);
    });
    kept_ = keep_;
    return rows_;
  }

 private:
  std::filesystem::path path_;
  bool keep_ = false, kept_ = false;
  std::vector<std::pair<std::vector<Sample>, std::vector<double>>> steps_;
  size_t rows_ = 0;
};

std::vector<double> counts_of(const std::vector<Sample>& rows, bool alpha) {
  std::vector<double> v;
  v.reserve(rows.size());
  for (const Sample& s : rows) v.push_back(alpha ? s.counts_alpha : s.counts_beta);
  return v;
}

}  // namespace

CalibrationReport calibrate_csv(const std::filesystem::path& path, const CalibrationOptions& opts) {
  if (opts.method != Method::differences) return calibrate(read_samples_csv(path), opts);
  const std::string origin = path.string();
  // Pass 1: the pooled deviations of every step's frames from their centres (calib/outliers.h).
  StepOutlierScreen screen[2] = {StepOutlierScreen(count_outlier_rule(count_outlier_floor(std::nullopt))),
                                 StepOutlierScreen(count_outlier_rule(count_outlier_floor(std::nullopt)))};
  DwellSteps steps(path);
  if (opts.reject_outliers) {
    steps.each([&](const std::vector<Sample>& rows, const std::vector<double>&) {
      screen[0].pool_step(counts_of(rows, true));
      screen[1].pool_step(counts_of(rows, false));
    });
  }
  // A later pass: a step's frames judged by the rule at the pooled sigma (a step's frames are all
  // it takes), each row with its flags.
  auto judged = [&](const std::function<void(const Sample&, OutlierAxes, double)>& on_row) {
    return steps.each([&](const std::vector<Sample>& rows, const std::vector<double>& temps) {
      std::vector<bool> f[2];
      if (opts.reject_outliers) {
        f[0] = screen[0].judge(counts_of(rows, true));
        f[1] = screen[1].judge(counts_of(rows, false));
      }
      for (size_t q = 0; q < rows.size(); ++q) {
        on_row(rows[q], opts.reject_outliers ? OutlierAxes{f[0][q], f[1][q]} : OutlierAxes{}, temps[q]);
      }
    });
  };
  std::optional<double> rule_noise = opts.count_noise_counts;
  std::string rule_noise_source = opts.count_noise_source;
  // Pass 2 (noise not given): the within-dwell scatter without the gross spikes, for the floor.
  if (opts.reject_outliers) {
    std::optional<double> noise = opts.count_noise_counts;
    if (!noise) {
      CountNoiseEstimator est;
      DwellBuilder b(origin);
      auto take = [&](const Dwell& d) {
        CountScatter two[2];
        if (!count_scatters(d, two)) return;
        est.add(two[0]);
        est.add(two[1]);
      };
      judged([&](const Sample& s, OutlierAxes o, double) {
        if (auto d = b.add(s, o)) take(*d);
      });
      if (auto d = b.flush()) take(*d);
      noise = est.estimate();
      rule_noise = noise;
      rule_noise_source = noise ? "within-dwell scatter" : "unknown";
    }
    if (noise) {
      for (auto& sc : screen) sc.set_min_sigma(count_outlier_floor(noise));
    }
  }
  // Pass 3: the dwells, into the streaming calibrator.
  StreamingCalibrator cal(opts, origin);
  DwellBuilder b(origin);
  const size_t rows = judged([&](const Sample& row, OutlierAxes o, double temp_c) {
    Sample s = row;
    // A raw recording: the reference's errors come off its angles before they enter a dwell.
    if (opts.reference && opts.correct_reference) {
      correct_reference_angles(*opts.reference, opts.mount, s.ref_pitch_arcsec, s.ref_yaw_arcsec);
    }
    if (auto d = b.add(s, o, temp_c)) cal.add_dwell(*d);
  });
  if (auto d = b.flush()) cal.add_dwell(*d);
  cal.set_samples(rows);
  // Nothing to pair (no nulls, no offsets, no dwells): the batch calibrator says what is missing.
  if (cal.pairs() == 0) return calibrate(read_samples_csv(path), opts);
  CalibrationReport rep = cal.finish();
  if (opts.reject_outliers) {
    rep.outliers.count_noise_counts = rule_noise;
    rep.outliers.count_noise_source = rule_noise_source;
  }
  return rep;
}

}  // namespace fpss
