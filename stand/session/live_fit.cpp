#include "stand/session/live_fit.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "calib/errors.h"
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
  // No estimate yet leaves the refresh budget unspent, so the first valid one is published at once.
  if (!est.valid) return std::nullopt;
  last_ = now;
  est_ = est;
  FitUpdated f;
  f.points = points;
  f.pairs = est.pairs;
  f.rms_pitch_arcsec = est.rms_pitch_arcsec;
  f.rms_yaw_arcsec = est.rms_yaw_arcsec;
  auto finite_or_nan = [](double v) { return std::isfinite(v) ? v : std::numeric_limits<double>::quiet_NaN(); };
  f.sigma_max_pitch_arcsec = finite_or_nan(sigma(fit::Axis::alpha, run_ranges_));
  f.sigma_max_yaw_arcsec = finite_or_nan(sigma(fit::Axis::beta, run_ranges_));
  text_ = fmt::format("live residual rms pitch {:.2f} yaw {:.2f} arcsec ({} pairs)", est.rms_pitch_arcsec,
                      est.rms_yaw_arcsec, est.pairs);
  if (std::isfinite(f.sigma_max_pitch_arcsec) && std::isfinite(f.sigma_max_yaw_arcsec)) {
    text_ += fmt::format(", 1-sigma {:.3f}/{:.3f}", f.sigma_max_pitch_arcsec, f.sigma_max_yaw_arcsec);
  }
  return f;
}

std::vector<LiveFit::PointResidual> LiveFit::residuals(int64_t point, const PointStats& st) {
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
  // Which sensor axes the group's points move: both, or the one the stand axis is mounted on.
  const bool both = a.until_both_axes;
  const auto sensor = a.axis == StandAxis::pitch ? axes_.pitch_axis : axes_.yaw_axis;
  double worst = 0;
  if (both || sensor == AxisMapping::alpha) worst = std::max(worst, sigma(fit::Axis::alpha, it->second));
  if (both || sensor == AxisMapping::beta) worst = std::max(worst, sigma(fit::Axis::beta, it->second));
  return worst;
}

}  // namespace fpss
