#include "calib/streaming.h"

#include <cmath>
#include <stdexcept>

#include "calib/errors.h"
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
}

void StreamingCalibrator::add_sample(const Sample& s) {
  ++samples_;
  if (auto d = builder_.add(s)) take_dwell(*d);
}

void StreamingCalibrator::add_dwell(const Dwell& d) {
  if (d.phase != Phase::null && d.phase != Phase::offset) return;
  take_dwell(d);
}

void StreamingCalibrator::take_dwell(const Dwell& d) {
  const size_t index = first_recent_ + recent_.size();
  if (d.phase == Phase::offset) ++offset_dwells_;
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
  gram_pitch_.add(pitch_.n_plus.back(), pitch_.n_minus.back(), pitch_.y_arcsec.back());
  gram_yaw_.add(yaw_.n_plus.back(), yaw_.n_minus.back(), yaw_.y_arcsec.back());
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
  if (auto d = builder_.flush()) take_dwell(*d);
  CalibrationReport rep;
  rep.method = Method::differences;
  rep.source = source_;
  rep.unit = opts_.unit.empty() && opts_.init ? opts_.init->unit : opts_.unit;
  rep.samples = samples_;
  rep.null_dwells = null_dwells_;
  rep.offset_dwells = offset_dwells_;
  rep.pairs = pairs();
  fit::check_axis(pitch_, fit::Axis::alpha, source_);
  fit::check_axis(yaw_, fit::Axis::beta, source_);
  rep.pitch = fit::fit_axis(pitch_, gram_pitch_, fit::Axis::alpha, opts_);
  rep.yaw = fit::fit_axis(yaw_, gram_yaw_, fit::Axis::beta, opts_);
  return rep;
}

}  // namespace fpss
