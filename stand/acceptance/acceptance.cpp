#include "stand/acceptance/acceptance.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "base/errors.h"
#include "calib/compare.h"
#include "calib/outliers.h"
#include "calib/units.h"
#include "stand/acceptance/judged_dwells.h"
#include "stand/report/report.h"

namespace fpss {
namespace fs = std::filesystem;

// Roles

std::map<int64_t, PointRole> acceptance_roles(const Procedure& proc, const Plan& plan) {
  std::vector<std::string> problems;
  size_t calibrate_at = 0, calibrates = 0;
  for (const auto& s : proc.steps) {
    if (std::holds_alternative<CalibrateStep>(s.body)) {
      ++calibrates;
      if (!calibrate_at) calibrate_at = s.index;
    }
  }
  if (calibrates != 1) {
    problems.push_back(fmt::format("needs exactly one calibrate step, has {}", calibrates));
  }
  bool cal_grid = false, ver_grid = false, rest = false;
  for (const auto& s : proc.steps) {
    const bool after = calibrate_at && s.index > calibrate_at;
    const std::string where = fmt::format("step {} ({}, line {})", s.index, s.type, s.mark.line);
    if (std::holds_alternative<GridStep>(s.body)) {
      (after ? ver_grid : cal_grid) = true;
    } else if (std::holds_alternative<SampleStep>(s.body)) {
      if (!after) problems.push_back(where + ": a sample step before calibrate would enter the fit; put rest dwells after it");
      rest = true;
    } else if (std::holds_alternative<SlewStep>(s.body)) {
      problems.push_back(where + ": slews have no role in an acceptance (calibration grid, verification grid, rest dwells)");
    }
  }
  if (!cal_grid) problems.push_back("needs a null_offset_grid before the calibrate step (the calibration)");
  if (!ver_grid) problems.push_back("needs a null_offset_grid after the calibrate step (the verification)");
  if (!rest) problems.push_back("needs sample steps after the calibrate step (rest dwells for the jitter)");
  if (!problems.empty()) {
    std::string msg = fmt::format("{}: not an acceptance procedure:", proc.origin);
    for (const auto& p : problems) msg += "\n  " + p;
    throw InputError(msg);
  }
  std::map<int64_t, PointRole> roles;
  for (const auto& a : plan.actions) {
    if (!a.is_point()) continue;
    const bool after = a.step_index > calibrate_at;
    PointRole r = PointRole::calibration;
    if (a.kind == Action::Kind::dwell && after) {
      r = std::holds_alternative<SampleStep>(proc.steps.at(a.step_index - 1).body) ? PointRole::rest
                                                                                   : PointRole::verification;
    }
    roles[a.point + 1] = r;
  }
  return roles;
}

// Judging

namespace {

using namespace judged;

const char* axis_label(int ax) { return ax == 0 ? "pitch (alpha)" : "yaw (beta)"; }

Criterion make(const std::string& id, const std::string& title, const std::string& axis, const Limit& lim,
               const std::string& key, const std::string& relation, const std::string& unit) {
  Criterion c;
  c.id = id;
  c.title = title;
  c.axis = axis;
  c.limit = lim.value;
  c.relation = relation;
  c.unit = unit;
  c.limit_key = key;
  c.source = lim.source;
  return c;
}

// A criterion judged on one axis: its id ends in the axis's name, its title in the axis's label.
Criterion make_for_axis(int ax, const std::string& id, const std::string& title, const Limit& lim,
                        const std::string& key, const std::string& relation, const std::string& unit) {
  return make(id + "_" + axis_name(ax), fmt::format("{}, {}", title, axis_label(ax)), axis_name(ax), lim, key,
              relation, unit);
}

// The measured value and its budget; decide() judges it once every criterion is settled.
void settle(Criterion& c, std::optional<double> measured, std::vector<BudgetEntry> budget, std::string detail) {
  c.measured = measured;
  c.budget = std::move(budget);
  c.combined = combine(c.budget);
  c.uncertainty = c.combined.u;
  c.detail = std::move(detail);
  if (!measured || !std::isfinite(*measured)) c.measured.reset();
}

// One criterion under the rule (and under the simple rule, for the certificate's why). A value
// exactly at the limit passes the simple rule: the limits are the largest (smallest) acceptable values.
void decide_criterion(Criterion& c, const DecisionRule& rule) {
  if (!c.measured) {
    c.decision = Decision{Outcome::fail, c.limit, 1.0};
    c.simple_outcome = Outcome::fail;
  } else {
    const bool upper = c.relation == "<=";
    const Combined& k = c.combined;
    c.decision = decide(rule, *c.measured, c.limit, upper, k.u, k.dof_eff, k.U);
    c.simple_outcome = decide(DecisionRule{}, *c.measured, c.limit, upper, k.u, k.dof_eff, k.U).outcome;
  }
  c.passed = c.decision.outcome == Outcome::pass;
}

std::string where_text(const DwellStats& d) {
  return fmt::format("step {} at pitch {:+.4f} deg, yaw {:+.4f} deg", d.step, d.ref[0] / kArcsecPerDeg,
                     d.ref[1] / kArcsecPerDeg);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// What the reduction left out of these dwells, for a criterion's detail ("" when nothing).
std::string left_out(const std::vector<const DwellStats*>& dwells) {
  size_t n[2] = {0, 0};
  for (const auto* d : dwells) {
    n[0] += d->outliers[0];
    n[1] += d->outliers[1];
  }
  if (n[0] + n[1] == 0) return "";
  return fmt::format("; outlier frames left out: pitch {}, yaw {} (criterion outlier_frames)", n[0], n[1]);
}

// The dwell whose `size` (never negative) is largest, the first of equals; `at` is null for no dwells.
struct WorstDwell {
  const DwellStats* at = nullptr;
  double size = -1;
};
template <typename Size>
WorstDwell worst_dwell(const std::vector<const DwellStats*>& dwells, Size size) {
  WorstDwell w;
  for (const auto* d : dwells) {
    const double s = size(*d);
    if (s > w.size) w = {d, s};
  }
  return w;
}

}  // namespace

std::vector<std::string> Judgement::failed() const {
  std::vector<std::string> f;
  for (const auto& c : criteria) {
    if (c.decision.outcome == Outcome::fail) f.push_back(c.id);
  }
  return f;
}

std::vector<std::string> Judgement::conditional() const {
  std::vector<std::string> f;
  for (const auto& c : criteria) {
    if (c.decision.outcome == Outcome::conditional) f.push_back(c.id);
  }
  return f;
}

namespace {

// One judgement in the making: the data, the limits, the dwells by role; one method per group
// of criteria, in the certificate's order.
struct Judging {
  Judging(const AcceptanceData& d, const AcceptanceLimits& limits);
  void outlier_criterion();
  void residual_criteria();
  void accuracy_criteria();
  void jitter_criteria();
  void coverage_criteria();
  void sun_criterion();
  void consistency_criterion();
  void judged_points();

  const AcceptanceData& data;
  const AcceptanceLimits& L;
  const CoefficientSet* cal;
  Reduction reduced;
  std::vector<DwellStats> dwells;
  std::string no_cal;
  double radius_arcsec;
  std::vector<const DwellStats*> ver_off, ver_null, rest, calib, ver_in;
  nlohmann::json residuals;
  Judgement J;
};

Judging::Judging(const AcceptanceData& d, const AcceptanceLimits& limits)
    : data(d), L(limits), cal(d.calibration ? &*d.calibration : nullptr),
      reduced(reduce(d.samples, cal ? reduction_options_of(cal->extra, "calibration.json") : ReductionOptions{})),
      dwells(dwell_stats(reduced, d, cal)),
      no_cal("not measured: the run has no calibration" + (d.run_reason.empty() ? std::string() : " (" + d.run_reason + ")")),
      radius_arcsec(limits.accuracy_radius_arcmin.value * 60.0),
      residuals(cal && cal->extra.contains("residuals") ? cal->extra["residuals"] : nlohmann::json()) {
  for (const auto& w : dwells) {
    if (w.role == PointRole::calibration) calib.push_back(&w);
    if (w.role == PointRole::rest) rest.push_back(&w);
    if (w.role == PointRole::verification) (w.phase == Phase::null ? ver_null : ver_off).push_back(&w);
  }
  for (const auto* w : ver_off) {
    if (std::hypot(w->ref[0], w->ref[1]) <= radius_arcsec + 1e-6) ver_in.push_back(w);
  }
}

void Judging::outlier_criterion() {
  // 0. Frames far from their dwell with a valid CRC: the unit's glitches, judged by name rather
  // than left to inflate accuracy and jitter (which are measured without them).
  Criterion c = make("outlier_frames", "Outlier frames (share of dwell frames, worse axis)", "",
                     L.outlier_frames_fraction, "outlier_frames_fraction", "<=", "fraction");
  const OutlierSummary& o = reduced.outliers;
  J.outliers = o;
  if (o.frames == 0) {
    settle(c, std::nullopt, {}, "not measured: the run recorded no dwell frames");
  } else if (!o.applied) {
    settle(c, std::nullopt, {}, "not measured: the outlier rule was off for this calibration");
  } else {
    const double share = o.worst_share();
    // Binomial 1-sigma of the share (at least one frame's worth when none was seen).
    const double n = static_cast<double>(o.frames);
    const double u = std::sqrt(std::max(share, 1.0 / n) * (1 - share) / n);
    settle(c, share, {{"binomial count of the outlier frames", 'A', 1.0, u, dof_of(o.frames)}},
           fmt::format("{} of {} dwell frames lie more than {} robust sigmas from their dwell: pitch {} ({:.2f} %), "
                       "yaw {} ({:.2f} %); left out of every dwell mean, accuracy and jitter",
                       o.any.outlier_frames, o.frames, OutlierRule{}.threshold_sigma, o.alpha.outlier_frames,
                       100 * o.alpha.share(o.frames), o.beta.outlier_frames, 100 * o.beta.share(o.frames)));
  }
  J.criteria.push_back(c);
}

void Judging::residual_criteria() {
  // 1. Calibration residuals, Table 1 form (from the calibrator's own summary in calibration.json).
  for (int ax = 0; ax < 2; ++ax) {
    const std::string a = axis_name(ax);
    Criterion mean = make_for_axis(ax, "residual_mean", "Calibration residuals, mean |r|", L.residual_mean_abs_arcsec,
                                   "residual_mean_abs_arcsec", "<=", "arcsec");
    Criterion max = make_for_axis(ax, "residual_max", "Calibration residuals, max |r|", L.residual_max_abs_arcsec,
                                  "residual_max_abs_arcsec", "<=", "arcsec");
    if (!residuals.is_object() || !residuals.contains(a)) {
      settle(mean, std::nullopt, {}, cal ? "not measured: calibration.json has no residuals for " + a : no_cal);
      settle(max, std::nullopt, {}, cal ? "not measured: calibration.json has no residuals for " + a : no_cal);
    } else {
      const auto& r = residuals[a];
      // A double default: NAN is a float, and value() returns its default's type (the figures
      // came out rounded to 7 digits, unlike calibration.json's).
      const double nan = std::numeric_limits<double>::quiet_NaN();
      const double m = r.value("mean_abs_arcsec", nan), sdv = r.value("sd_arcsec", 0.0), mx = r.value("max_abs_arcsec", nan);
      const double n = r.value("points", 0.0);
      // One change's noise: two dwell means, each with its standard error (the median dwell's parts).
      std::vector<double> noise, quant, ref, frames;
      for (const auto* d : calib) {
        noise.push_back(d->noise[ax]);
        quant.push_back(d->quant[ax]);
        ref.push_back(d->ref_noise[ax]);
        frames.push_back(static_cast<double>(d->frames));
      }
      std::vector<BudgetEntry> change{
          {"sensor noise (two dwell means, median dwell)", 'A', std::sqrt(2.0), std::sqrt(2.0) * median(noise),
           dof_of(static_cast<size_t>(median(frames)))},
          {"quantisation (one count, LSB / sqrt(12), two dwell means)", 'B', std::sqrt(2.0), std::sqrt(2.0) * median(quant), kInfDof}};
      if (median(ref) > 0) {
        change.push_back({"reference noise (two dwell means, median dwell)", 'A', std::sqrt(2.0), std::sqrt(2.0) * median(ref),
                          dof_of(static_cast<size_t>(median(frames)))});
      }
      std::vector<BudgetEntry> scatter;
      if (n > 0) scatter.push_back({"scatter of the calibration's changes (sd / sqrt(n))", 'A', 1.0 / std::sqrt(n), sdv / std::sqrt(n), dof_of(static_cast<size_t>(n))});
      settle(mean, m, scatter,
             fmt::format("{} changes null <-> offset (Table 1: mean |r| +- sd = {:.3f} +- {:.3f})", n, m, sdv));
      settle(max, mx, change,
             fmt::format("largest of {} changes; uncertainty = noise of one change (two dwell means)", n));
    }
    J.criteria.push_back(mean);
    J.criteria.push_back(max);
  }
}

void Judging::accuracy_criteria() {
  // 2. Accuracy on the verification points the fit never saw, within the radius.
  for (int ax = 0; ax < 2; ++ax) {
    const auto error_size = [ax](const DwellStats& d) { return std::fabs(d.mean[ax] - d.ref[ax]); };
    const std::optional<TemperatureSensitivity> temp = temperature_sensitivity(cal, ax);
    Criterion rms3 = make_for_axis(ax, "accuracy_3sigma", "Accuracy, 3 sigma (3 x RMS error)", L.accuracy_3sigma_arcsec,
                                   "accuracy_3sigma_arcsec", "<=", "arcsec");
    Criterion worst = make_for_axis(ax, "accuracy_worst_point", "Accuracy, worst verification point",
                                    L.accuracy_worst_point_arcsec, "accuracy_worst_point_arcsec", "<=", "arcsec");
    Criterion centre = make_for_axis(ax, "accuracy_centre", "Accuracy at the centre (null dwells)",
                                     L.accuracy_centre_arcsec, "accuracy_centre_arcsec", "<=", "arcsec");
    if (!cal) {
      settle(rms3, std::nullopt, {}, no_cal);
      settle(worst, std::nullopt, {}, no_cal);
      settle(centre, std::nullopt, {}, no_cal);
    } else {
      if (ver_in.empty()) {
        settle(rms3, std::nullopt, {}, "not measured: no verification point within the radius");
        settle(worst, std::nullopt, {}, "not measured: no verification point within the radius");
      } else {
        double ss = 0;
        for (const auto* d : ver_in) ss += sq(d->mean[ax] - d->ref[ax]);
        const auto [at, w] = worst_dwell(ver_in, error_size);
        const double n = static_cast<double>(ver_in.size());
        const double v3 = 3.0 * std::sqrt(ss / n);
        // An RMS about zero (the reference), not about its own mean: n degrees of freedom.
        std::vector<BudgetEntry> rms_budget{{"scatter of the verification errors (RMS / sqrt(2n))", 'A', 3.0, v3 / std::sqrt(2.0 * n), n}};
        add_rms_terms(rms_budget, data, ver_in, ax, v3 / 3.0);
        add_temperature(rms_budget, temp, rms_temperature_offset(ver_in, temp), 3.0, "RMS of the points' temperatures");
        settle(rms3, v3, rms_budget,
               fmt::format("{} verification points within {} arcmin; error = calibrated angle - reference, "
                           "mean over each dwell's frames{}",
                           ver_in.size(), L.accuracy_radius_arcmin.value, left_out(ver_in)));
        std::vector<BudgetEntry> worst_budget = dwell_budget(*at, ax);
        add_selection_lift(worst_budget, ver_in, ax);
        add_reference_terms(worst_budget, data, ver_in, ax);
        add_temperature(worst_budget, temp, temperature_offset(*at, temp), 1.0, "the point's temperature");
        settle(worst, w, worst_budget,
               fmt::format("{:+.3f} arcsec at {}{}", at->mean[ax] - at->ref[ax], where_text(*at), left_out({at})));
      }
      if (ver_null.empty()) {
        settle(centre, std::nullopt, {}, "not measured: no verification null dwell");
      } else {
        const auto [at, w] = worst_dwell(ver_null, error_size);
        std::vector<BudgetEntry> centre_budget = dwell_budget(*at, ax);
        add_selection_lift(centre_budget, ver_null, ax);
        add_reference_terms(centre_budget, data, ver_null, ax);
        add_temperature(centre_budget, temp, temperature_offset(*at, temp), 1.0, "the dwell's temperature");
        settle(centre, w, centre_budget,
               fmt::format("{} null dwells after the calibration; worst {:+.3f} arcsec at step {}{}", ver_null.size(),
                           at->mean[ax] - at->ref[ax], at->step, left_out(ver_null)));
      }
    }
    J.criteria.push_back(rms3);
    J.criteria.push_back(worst);
    J.criteria.push_back(centre);
  }
}

void Judging::jitter_criteria() {
  // 3. Jitter at rest.
  for (int ax = 0; ax < 2; ++ax) {
    Criterion jit = make_for_axis(ax, "jitter_3sigma", "Jitter at rest, 3 sigma", L.jitter_3sigma_arcsec,
                                  "jitter_3sigma_arcsec", "<=", "arcsec");
    if (!cal) {
      settle(jit, std::nullopt, {}, no_cal);
    } else if (rest.empty()) {
      settle(jit, std::nullopt, {}, "not measured: no rest dwell was recorded");
    } else {
      const auto [at, w] = worst_dwell(rest, [ax](const DwellStats& d) { return 3.0 * d.sd_detrended[ax]; });
      // A detrended sd has frames - 2 degrees of freedom.
      const double nu = at->frames > 2 ? static_cast<double>(at->frames - 2) : 1.0;
      const double u = at->frames > 2 ? w / std::sqrt(2.0 * nu) : w;
      settle(jit, w, {{"sensor noise (sampling of the SD, frames - 2 dof)", 'A', 3.0, u, nu}},
             fmt::format("worst of {} rest dwells: {} ({} frames, linear trend removed){}", rest.size(),
                         where_text(*at), at->frames, left_out(rest)));
    }
    J.criteria.push_back(jit);
  }
}

void Judging::coverage_criteria() {
  // 4. Field coverage: the calibration's range and the verification's reach, per axis.
  for (int ax = 0; ax < 2; ++ax) {
    const std::string a = axis_name(ax);
    Criterion range = make_for_axis(ax, "calibrated_range", "Calibrated range", L.calibrated_range_deg,
                                    "calibrated_range_deg", ">=", "deg");
    if (!residuals.is_object() || !residuals.contains(a) || !residuals[a].contains("range_deg") ||
        !residuals[a]["range_deg"].is_array() || residuals[a]["range_deg"].size() != 2) {
      settle(range, std::nullopt, {}, cal ? "not measured: calibration.json has no range_deg for " + a : no_cal);
    } else {
      const double lo = residuals[a]["range_deg"][0].get<double>(), hi = residuals[a]["range_deg"][1].get<double>();
      settle(range, std::min(-lo, hi), {},
             fmt::format("reference angles of the calibration dwells span {:+.4f} .. {:+.4f} deg (the smaller side)", lo, hi));
    }
    J.criteria.push_back(range);

    Criterion ext = make_for_axis(ax, "verified_extent", "Verified extent", L.verified_extent_deg,
                                  "verified_extent_deg", ">=", "deg");
    if (ver_in.empty()) {
      settle(ext, std::nullopt, {}, "not measured: no verification point within the radius");
    } else {
      double lo = 0, hi = 0;
      for (const auto* d : ver_in) {
        lo = std::min(lo, d->ref[ax]);
        hi = std::max(hi, d->ref[ax]);
      }
      settle(ext, std::min(-lo, hi) / kArcsecPerDeg, {},
             fmt::format("verification points span {:+.4f} .. {:+.4f} deg (the smaller side)", lo / kArcsecPerDeg,
                         hi / kArcsecPerDeg));
    }
    J.criteria.push_back(ext);
  }
  {
    Criterion n = make("verification_points", "Verification points within the radius", "", L.verification_points_min,
                       "verification_points_min", ">=", "points");
    settle(n, static_cast<double>(ver_in.size()), {},
           fmt::format("{} offset points within {} arcmin of the centre ({} verification offset points in all)",
                       ver_in.size(), L.accuracy_radius_arcmin.value, ver_off.size()));
    J.criteria.push_back(n);
  }
}

void Judging::sun_criterion() {
  // 5. Sun present over the field: every planned point measured, every frame valid.
  {
    Criterion sun = make("sun_present", "Sun present with valid frames over the field", "", L.sun_present_fraction,
                         "sun_present_fraction", ">=", "fraction");
    const double planned = static_cast<double>(std::max<size_t>(data.points_planned, 1));
    double frac = static_cast<double>(dwells.size()) / planned;
    size_t bad_frames = 0;
    if (data.samples.has_column("sensor_status")) {
      const auto status = data.samples.numeric_column("sensor_status");
      for (double st : status) {
        const auto b = static_cast<unsigned>(st);
        if ((b & 0x7u) != 0x7u || (b & 0x8u)) ++bad_frames;  // sun present, alpha and beta valid, not saturated
      }
      if (!status.empty()) {
        frac = std::min(frac, 1.0 - static_cast<double>(bad_frames) / static_cast<double>(status.size()));
      }
    }
    std::string detail = fmt::format("{} of {} planned points measured with valid frames", dwells.size(),
                                     data.points_planned);
    if (bad_frames) detail += fmt::format("; {} recorded frames not valid", bad_frames);
    if (!data.run_completed) detail += fmt::format("; the run stopped: {}", data.run_reason);
    settle(sun, std::min(frac, 1.0), {}, detail);
    J.criteria.push_back(sun);
  }
}

void Judging::consistency_criterion() {
  // 6. Consistency with the unit's last accepted or imported calibration (only when it has one).
  if (data.previous) {
    Criterion con = make("consistency", "Change since the unit's last accepted or imported calibration (max |B - A|, +-0.35 deg)", "",
                         L.consistency_arcsec, "consistency_arcsec", "<=", "arcsec");
    if (!cal) {
      settle(con, std::nullopt, {}, no_cal);
    } else {
      try {
        const DriftCheck d = check_drift(*data.previous, *cal, L.consistency_arcsec.value);
        std::vector<BudgetEntry> fit;
        if (cal->extra.contains("uncertainties")) {
          const auto& un = cal->extra["uncertainties"];
          const int worst_ax = d.worst_axis == "alpha" ? 0 : 1;
          const char* key = axis_name(worst_ax);
          if (un.contains(key) && un[key].contains("angle_sigma_max_arcsec") && un[key]["angle_sigma_max_arcsec"].is_number()) {
            // The fit's chi^2 degrees of freedom, when calibration.json gives them.
            const double dof = un.contains("chi2_dof") && un["chi2_dof"].is_number() && un["chi2_dof"].get<double>() > 0
                                   ? un["chi2_dof"].get<double>() : kInfDof;
            fit.push_back({"model and fit (this calibration's angle sigma, worst axis)", 'A', 1.0,
                           un[key]["angle_sigma_max_arcsec"].get<double>(), dof});
          }
        }
        settle(con, d.worst_arcsec, fit,
               fmt::format("against {}: alpha max {:.3f}, beta max {:.3f} arcsec ({:.3f} with the null shift removed)",
                           data.previous_name, d.comparison.alpha.max_abs_arcsec, d.comparison.beta.max_abs_arcsec,
                           d.worst_shape_arcsec));
      } catch (const InputError& e) {
        settle(con, std::nullopt, {}, std::string("not measured: ") + e.what());
      }
    }
    J.criteria.push_back(con);
  }
}

void Judging::judged_points() {
  for (const auto& d : dwells) {
    if (d.role == PointRole::calibration) continue;
    JudgedPoint p;
    p.step = d.step;
    p.role = d.role;
    p.phase = d.phase;
    p.ref_pitch_arcsec = d.ref[0];
    p.ref_yaw_arcsec = d.ref[1];
    p.frames = d.frames;
    p.outliers_pitch = d.outliers[0];
    p.outliers_yaw = d.outliers[1];
    if (cal) {
      p.error_pitch_arcsec = d.mean[0] - d.ref[0];
      p.error_yaw_arcsec = d.mean[1] - d.ref[1];
      p.se_pitch_arcsec = d.se[0];
      p.se_yaw_arcsec = d.se[1];
      p.jitter3_pitch_arcsec = 3.0 * d.sd_detrended[0];
      p.jitter3_yaw_arcsec = 3.0 * d.sd_detrended[1];
    }
    J.points.push_back(p);
  }
}

}  // namespace

Judgement judge(const AcceptanceData& data, const AcceptanceLimits& L) {
  Judging g(data, L);
  g.outlier_criterion();
  g.residual_criteria();
  g.accuracy_criteria();
  g.jitter_criteria();
  g.coverage_criteria();
  g.sun_criterion();
  g.consistency_criterion();
  g.judged_points();
  g.J.rule = L.decision_rule;
  g.J.outcome = Outcome::pass;
  for (auto& c : g.J.criteria) {
    decide_criterion(c, L.decision_rule);
    if (c.decision.outcome == Outcome::fail) g.J.outcome = Outcome::fail;
    if (c.decision.outcome == Outcome::conditional && g.J.outcome == Outcome::pass) g.J.outcome = Outcome::conditional;
  }
  g.J.passed = g.J.outcome == Outcome::pass;
  return g.J;
}

}  // namespace fpss
