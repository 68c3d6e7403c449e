#include "stand/session/live_fit.h"

#include <fmt/format.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "base/errors.h"
#include "calib/transfer_function.h"

namespace fpss {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

void widen(std::optional<std::array<double, 2>>& r, double v) {
  if (!r) r = std::array<double, 2>{v, v};
  (*r)[0] = std::min((*r)[0], v);
  (*r)[1] = std::max((*r)[1], v);
}

}  // namespace

LiveFit::LiveFit(const Plan& plan, const AxisMapping& axes) : cal_(CalibrationOptions{}, "live"), axes_(axes) {
  run_ranges_ = ranges_of(plan, 0);
  for (const auto& a : plan.actions) {
    if (a.until_group >= 0 && !step_ranges_.count(a.step_index)) step_ranges_[a.step_index] = ranges_of(plan, a.step_index);
  }
  worker_ = std::thread([this] { work(); });
}

LiveFit::~LiveFit() {
  {
    std::lock_guard lk(m_);
    stop_ = true;
  }
  cv_.notify_one();
  worker_.join();
}

void LiveFit::add(const Sample& s) {
  std::lock_guard fl(fit_m_);
  cal_.add_sample(s);
}

int64_t LiveFit::take_queued() {
  std::vector<Sample> rows;
  int64_t points = 0;
  {
    std::lock_guard lk(m_);
    rows.swap(queued_);
    points = queued_points_;
  }
  for (const auto& r : rows) cal_.add_sample(r);
  return points;
}

void LiveFit::work() {
  // The lowest priority: the estimate is for the operator's eyes, and on two cores a fit competing
  // with the emulator's sensor thread or the engine delays frames and moves. Failing to lower it
  // changes nothing but that.
  ::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 19);
  for (;;) {
    {
      std::unique_lock lk(m_);
      cv_.wait(lk, [&] { return stop_ || !queued_.empty(); });
      if (stop_) return;
    }
    std::lock_guard fl(fit_m_);
    try {
      auto f = update(take_queued(), false);
      std::lock_guard lk(m_);
      if (f) ready_ = std::move(f);
    } catch (const std::exception& e) {
      std::lock_guard lk(m_);
      error_ = e.what();
      return;
    }
  }
}

std::optional<FitUpdated> LiveFit::point_done(const std::vector<Sample>& rows, int64_t points, bool force) {
  {
    std::lock_guard lk(m_);
    if (!error_.empty()) throw std::runtime_error(error_);
    queued_.insert(queued_.end(), rows.begin(), rows.end());
    queued_points_ = points;
  }
  if (force) {
    std::lock_guard fl(fit_m_);
    take_queued();
    auto f = update(points, true);
    std::lock_guard lk(m_);
    ready_.reset();  // older than this one
    return f;
  }
  cv_.notify_one();
  std::lock_guard lk(m_);
  return std::exchange(ready_, std::nullopt);
}

LiveFit::Ranges LiveFit::ranges_of(const Plan& plan, size_t step_index) const {
  Ranges r;
  for (const auto& a : plan.actions) {
    if (a.kind != Action::Kind::dwell || (step_index && a.step_index != step_index)) continue;
    const auto [alpha, beta] = axes_.sensor_from_stand(a.pitch_arcsec, a.yaw_arcsec);
    widen(r.pitch, alpha);
    widen(r.yaw, beta);
  }
  return r;
}

double LiveFit::sigma(fit::Axis axis, const Ranges& r) {
  const Range& range = axis == fit::Axis::alpha ? r.pitch : r.yaw;
  // A range of one angle (an axis the plan never moves) has no spread to judge a fit over.
  if (!range || !((*range)[1] > (*range)[0])) return kInf;
  const auto ck = std::make_tuple(static_cast<int>(axis), (*range)[0], (*range)[1]);
  auto it = cache_.find(ck);
  if (it != cache_.end() && it->second.pairs == cal_.pairs()) return it->second.sigma;
  double s = kInf;
  CalibrationOptions o = cal_.options();
  o.threads = 1;  // a small fit between points: the pool costs more than it gives
  (axis == fit::Axis::alpha ? o.sigma_range_pitch_arcsec : o.sigma_range_yaw_arcsec) = range;
  try {
    s = cal_.fit_so_far(axis, o).listed_sigma_max_arcsec();
  } catch (const DataError&) {
    // not enough changes of this axis yet
  } catch (const std::runtime_error&) {
    // the solver failed on too little data: no word yet
  }
  cache_[ck] = {cal_.pairs(), s};
  return s;
}

std::optional<FitUpdated> LiveFit::update(int64_t points, bool force) {
  const auto now = std::chrono::steady_clock::now();
  if (!force && now - last_ < std::chrono::milliseconds(500)) return std::nullopt;
  const auto est = cal_.current();
  // No estimate yet leaves the refresh budget unspent, so the first valid one is published as
  // soon as it allows.
  // A forced one (an adaptive stop) is published with what there is: an axis that has stopped
  // before the other has any offsets has its 1-sigma, and the residuals wait for both axes.
  if (!est.valid && !force) return std::nullopt;
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  auto finite_or_nan = [](double v) { return std::isfinite(v) ? v : kNaN; };
  FitUpdated f;
  f.points = points;
  f.pairs = est.pairs;
  f.rms_pitch_arcsec = est.valid ? est.rms_pitch_arcsec : kNaN;
  f.rms_yaw_arcsec = est.valid ? est.rms_yaw_arcsec : kNaN;
  f.sigma_max_pitch_arcsec = finite_or_nan(sigma(fit::Axis::alpha, run_ranges_));
  f.sigma_max_yaw_arcsec = finite_or_nan(sigma(fit::Axis::beta, run_ranges_));
  if (!est.valid && std::isnan(f.sigma_max_pitch_arcsec) && std::isnan(f.sigma_max_yaw_arcsec)) return std::nullopt;
  last_ = now;
  if (!est.valid) return f;
  std::string text = fmt::format("live residual rms pitch {:.2f} yaw {:.2f} arcsec ({} pairs)", est.rms_pitch_arcsec,
                                 est.rms_yaw_arcsec, est.pairs);
  if (std::isfinite(f.sigma_max_pitch_arcsec) && std::isfinite(f.sigma_max_yaw_arcsec)) {
    text += fmt::format(", 1-sigma {:.3f}/{:.3f}", f.sigma_max_pitch_arcsec, f.sigma_max_yaw_arcsec);
  }
  std::lock_guard lk(m_);
  est_ = est;
  text_ = std::move(text);
  return f;
}

std::string LiveFit::text() const {
  std::lock_guard lk(m_);
  return text_;
}

std::vector<LiveFit::PointResidual> LiveFit::residuals(int64_t point, const PointStats& st) {
  std::lock_guard lk(m_);
  if (st.rows > 0) unplotted_.push_back({point, st});
  std::vector<PointResidual> out;
  if (!est_) return out;
  for (const auto& [p, s] : unplotted_) {
    const double rp = rad_to_arcsec(transfer_angle(est_->alpha.data(), s.counts_alpha)) - s.ref_pitch_arcsec;
    const double ry = rad_to_arcsec(transfer_angle(est_->beta.data(), s.counts_beta)) - s.ref_yaw_arcsec;
    out.push_back({p, s.ref_pitch_arcsec, s.ref_yaw_arcsec, rp, ry});
  }
  unplotted_.clear();
  return out;
}

double LiveFit::until_sigma(const Action& a) {
  const auto it = step_ranges_.find(a.step_index);
  if (it == step_ranges_.end()) return kInf;
  std::lock_guard fl(fit_m_);
  take_queued();
  // Which sensor axes the group's points move: both, or the one the stand axis is mounted on.
  const bool both = a.until_both_axes;
  const auto sensor = a.axis == StandAxis::pitch ? axes_.pitch_axis : axes_.yaw_axis;
  double worst = 0;
  if (both || sensor == AxisMapping::alpha) worst = std::max(worst, sigma(fit::Axis::alpha, it->second));
  if (both || sensor == AxisMapping::beta) worst = std::max(worst, sigma(fit::Axis::beta, it->second));
  return worst;
}

}  // namespace fpss
