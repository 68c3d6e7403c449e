#include "stand/acceptance/acceptance.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "calib/compare.h"
#include "calib/errors.h"
#include "calib/text_file.h"
#include "calib/units.h"
#include "stand/report/report.h"
#include "procedures/yaml_diag.h"

namespace fpss {
namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// Limits

namespace {

struct LimitField {
  const char* key;
  Limit AcceptanceLimits::*member;
  bool positive;  // value must be > 0 (else >= 0)
};

constexpr LimitField kLimitFields[] = {
    {"residual_mean_abs_arcsec", &AcceptanceLimits::residual_mean_abs_arcsec, true},
    {"residual_max_abs_arcsec", &AcceptanceLimits::residual_max_abs_arcsec, true},
    {"accuracy_3sigma_arcsec", &AcceptanceLimits::accuracy_3sigma_arcsec, true},
    {"accuracy_worst_point_arcsec", &AcceptanceLimits::accuracy_worst_point_arcsec, true},
    {"accuracy_centre_arcsec", &AcceptanceLimits::accuracy_centre_arcsec, true},
    {"accuracy_radius_arcmin", &AcceptanceLimits::accuracy_radius_arcmin, true},
    {"jitter_3sigma_arcsec", &AcceptanceLimits::jitter_3sigma_arcsec, true},
    {"calibrated_range_deg", &AcceptanceLimits::calibrated_range_deg, false},
    {"verified_extent_deg", &AcceptanceLimits::verified_extent_deg, false},
    {"verification_points_min", &AcceptanceLimits::verification_points_min, false},
    {"sun_present_fraction", &AcceptanceLimits::sun_present_fraction, false},
    {"consistency_arcsec", &AcceptanceLimits::consistency_arcsec, true},
};

fs::path procedures_dir() {
  if (const char* env = std::getenv("FPSS_PROCEDURES_DIR"); env && *env) return env;
  return fs::path(FPSS_SOURCE_DIR) / "procedures";
}

}  // namespace

fs::path default_limits_path() { return procedures_dir() / "acceptance_limits.yaml"; }
fs::path default_acceptance_procedure_path() { return procedures_dir() / "acceptance.yaml"; }

AcceptanceLimits parse_acceptance_limits(const std::string& text, const std::string& origin) {
  Diagnostics d(origin);
  AcceptanceLimits out;
  out.origin = origin;
  out.sha256 = sha256_hex(text);
  const YAML::Node root = parse_yaml(text, d);
  if (!d.empty()) d.throw_if_any();
  MapReader top(root, "limits file", d);
  if (!top.ok()) d.throw_if_any();
  out.name = top.string("name").value_or("");
  out.description = top.string("description").value_or("");
  const YAML::Node limits = top.node("limits");
  if (!limits.IsDefined() || limits.IsNull()) {
    d.error(root, "limits file: missing field \"limits\" (a map of limit name -> {value, source})");
  } else {
    MapReader lr(limits, "limits", d);
    for (const auto& f : kLimitFields) {
      const YAML::Node n = lr.node(f.key);
      if (!n.IsDefined() || n.IsNull()) {
        d.error(limits, fmt::format("limits: missing \"{}\" (every limit must be given, with its source)", f.key));
        continue;
      }
      MapReader one(n, fmt::format("limits.{}", f.key), d);
      if (!one.ok()) continue;
      const auto v = f.positive ? one.positive("value", true) : one.non_negative("value", true);
      const auto src = one.string("source", true);
      if (src && src->find_first_not_of(" \t\r\n") == std::string::npos) {
        d.error(n, fmt::format("limits.{}: source must say where the number comes from", f.key));
      }
      one.finish();
      if (v) (out.*f.member).value = *v;
      if (src) (out.*f.member).source = *src;
    }
    lr.finish();
    if (out.sun_present_fraction.value > 1.0) {
      d.error(limits["sun_present_fraction"], "limits.sun_present_fraction: value is a fraction, at most 1");
    }
  }
  top.finish();
  d.throw_if_any();
  return out;
}

AcceptanceLimits load_acceptance_limits(const fs::path& path) {
  return parse_acceptance_limits(read_text_file(path, "the acceptance limits file"), path.string());
}

// ---------------------------------------------------------------------------------------------
// Roles

const char* to_string(PointRole r) {
  switch (r) {
    case PointRole::calibration: return "calibration";
    case PointRole::verification: return "verification";
    case PointRole::rest: return "rest";
  }
  return "?";
}

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

// ---------------------------------------------------------------------------------------------
// Judging

namespace {

struct DwellStats {
  int64_t step = 0;
  PointRole role = PointRole::calibration;
  Phase phase = Phase::null;
  size_t frames = 0;
  double ref[2] = {0, 0};
  double mean[2] = {0, 0};    // calibrated angle, arcsec
  double sd[2] = {0, 0};      // SD over frames
  double sd_detrended[2] = {0, 0};
  // Standard error of the mean angle: the frames' scatter over sqrt(k), and the count
  // quantisation (one count, uniform), which averaging over a still dwell does not remove.
  double se[2] = {0, 0};
};

double sq(double x) { return x * x; }

// Mean and SD of v, and the SD about a straight line in t (the dwell's drift removed).
void moments(const std::vector<double>& t, const std::vector<double>& v, double& mean, double& sd, double& sd_lin) {
  const size_t n = v.size();
  mean = 0;
  for (double x : v) mean += x;
  mean /= static_cast<double>(n);
  double ss = 0;
  for (double x : v) ss += sq(x - mean);
  sd = n > 1 ? std::sqrt(ss / static_cast<double>(n - 1)) : 0.0;
  if (n < 3) {
    sd_lin = sd;
    return;
  }
  double tm = 0;
  for (double x : t) tm += x;
  tm /= static_cast<double>(n);
  double stt = 0, stv = 0;
  for (size_t i = 0; i < n; ++i) {
    stt += sq(t[i] - tm);
    stv += (t[i] - tm) * (v[i] - mean);
  }
  const double slope = stt > 0 ? stv / stt : 0.0;
  double sr = 0;
  for (size_t i = 0; i < n; ++i) sr += sq(v[i] - mean - slope * (t[i] - tm));
  sd_lin = std::sqrt(sr / static_cast<double>(n - 2));
}

std::vector<DwellStats> dwell_stats(const AcceptanceData& data, const CoefficientSet* cal) {
  const SampleTable& s = data.samples;
  std::vector<DwellStats> out;
  size_t i = 0;
  while (i < s.size()) {
    size_t j = i;
    while (j < s.size() && s.step[j] == s.step[i]) ++j;
    DwellStats d;
    d.step = s.step[i];
    const auto role = data.roles.find(d.step);
    d.role = role == data.roles.end() ? PointRole::calibration : role->second;
    d.phase = s.phase[i];
    d.frames = j - i;
    std::vector<double> t(s.time_s.begin() + static_cast<long>(i), s.time_s.begin() + static_cast<long>(j));
    for (int ax = 0; ax < 2; ++ax) {
      const auto& refs = ax == 0 ? s.ref_pitch_arcsec : s.ref_yaw_arcsec;
      double r = 0;
      for (size_t k = i; k < j; ++k) r += refs[k];
      d.ref[ax] = r / static_cast<double>(d.frames);
      if (cal) {
        const AxisModel m = ax == 0 ? cal->alpha_model() : cal->beta_model();
        const auto& counts = ax == 0 ? s.counts_alpha : s.counts_beta;
        std::vector<double> v;
        v.reserve(d.frames);
        double mean_counts = 0;
        for (size_t k = i; k < j; ++k) {
          v.push_back(m.angle_arcsec(counts[k]));
          mean_counts += counts[k];
        }
        mean_counts /= static_cast<double>(d.frames);
        moments(t, v, d.mean[ax], d.sd[ax], d.sd_detrended[ax]);
        const double q = std::fabs(rad_to_arcsec(m.slope_rad_per_count(mean_counts))) / std::sqrt(12.0);
        d.se[ax] = std::sqrt(sq(d.sd[ax]) / static_cast<double>(d.frames) + q * q);
      }
    }
    out.push_back(d);
    i = j;
  }
  return out;
}

const char* axis_name(int ax) { return ax == 0 ? "pitch" : "yaw"; }
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

void settle(Criterion& c, std::optional<double> measured, double u, std::string detail) {
  c.measured = measured;
  c.uncertainty = u;
  c.detail = std::move(detail);
  if (!measured || !std::isfinite(*measured)) {
    c.measured.reset();
    c.passed = false;
    return;
  }
  // A value exactly at the limit passes: the limits are the largest (smallest) acceptable values.
  c.passed = c.relation == "<=" ? *measured <= c.limit : *measured >= c.limit;
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

}  // namespace

std::vector<std::string> Judgement::failed() const {
  std::vector<std::string> f;
  for (const auto& c : criteria) {
    if (!c.passed) f.push_back(c.id);
  }
  return f;
}

Judgement judge(const AcceptanceData& data, const AcceptanceLimits& L) {
  Judgement J;
  const CoefficientSet* cal = data.calibration ? &*data.calibration : nullptr;
  const std::vector<DwellStats> dwells = dwell_stats(data, cal);
  const std::string no_cal = "not measured: the run has no calibration" +
                             (data.run_reason.empty() ? std::string() : " (" + data.run_reason + ")");
  const double radius_arcsec = L.accuracy_radius_arcmin.value * 60.0;

  std::vector<const DwellStats*> ver_off, ver_null, rest, calib;
  for (const auto& d : dwells) {
    if (d.role == PointRole::calibration) calib.push_back(&d);
    if (d.role == PointRole::rest) rest.push_back(&d);
    if (d.role == PointRole::verification) (d.phase == Phase::null ? ver_null : ver_off).push_back(&d);
  }
  std::vector<const DwellStats*> ver_in;
  for (const auto* d : ver_off) {
    if (std::hypot(d->ref[0], d->ref[1]) <= radius_arcsec + 1e-6) ver_in.push_back(d);
  }

  // 1. Calibration residuals, Table 1 form (from the calibrator's own summary in calibration.json).
  const nlohmann::json residuals = cal && cal->extra.contains("residuals") ? cal->extra["residuals"] : nlohmann::json();
  for (int ax = 0; ax < 2; ++ax) {
    const std::string a = axis_name(ax);
    Criterion mean = make("residual_mean_" + a, fmt::format("Calibration residuals, mean |r|, {}", axis_label(ax)), a,
                          L.residual_mean_abs_arcsec, "residual_mean_abs_arcsec", "<=", "arcsec");
    Criterion max = make("residual_max_" + a, fmt::format("Calibration residuals, max |r|, {}", axis_label(ax)), a,
                         L.residual_max_abs_arcsec, "residual_max_abs_arcsec", "<=", "arcsec");
    if (!residuals.is_object() || !residuals.contains(a)) {
      settle(mean, std::nullopt, 0, cal ? "not measured: calibration.json has no residuals for " + a : no_cal);
      settle(max, std::nullopt, 0, cal ? "not measured: calibration.json has no residuals for " + a : no_cal);
    } else {
      const auto& r = residuals[a];
      const double m = r.value("mean_abs_arcsec", NAN), sdv = r.value("sd_arcsec", 0.0), mx = r.value("max_abs_arcsec", NAN);
      const double n = r.value("points", 0.0);
      // One change's noise: two dwell means, each with its standard error.
      std::vector<double> se;
      for (const auto* d : calib) {
        se.push_back(d->se[ax]);
      }
      settle(mean, m, n > 0 ? sdv / std::sqrt(n) : 0.0,
             fmt::format("{} changes null <-> offset (Table 1: mean |r| +- sd = {:.3f} +- {:.3f})", n, m, sdv));
      settle(max, mx, std::sqrt(2.0) * median(se),
             fmt::format("largest of {} changes; uncertainty = noise of one change (two dwell means)", n));
    }
    J.criteria.push_back(mean);
    J.criteria.push_back(max);
  }

  // 2. Accuracy on the verification points the fit never saw, within the radius.
  for (int ax = 0; ax < 2; ++ax) {
    const std::string a = axis_name(ax);
    Criterion rms3 = make("accuracy_3sigma_" + a, fmt::format("Accuracy, 3 sigma (3 x RMS error), {}", axis_label(ax)),
                          a, L.accuracy_3sigma_arcsec, "accuracy_3sigma_arcsec", "<=", "arcsec");
    Criterion worst = make("accuracy_worst_point_" + a, fmt::format("Accuracy, worst verification point, {}", axis_label(ax)),
                           a, L.accuracy_worst_point_arcsec, "accuracy_worst_point_arcsec", "<=", "arcsec");
    Criterion centre = make("accuracy_centre_" + a, fmt::format("Accuracy at the centre (null dwells), {}", axis_label(ax)),
                            a, L.accuracy_centre_arcsec, "accuracy_centre_arcsec", "<=", "arcsec");
    if (!cal) {
      settle(rms3, std::nullopt, 0, no_cal);
      settle(worst, std::nullopt, 0, no_cal);
      settle(centre, std::nullopt, 0, no_cal);
    } else {
      if (ver_in.empty()) {
        settle(rms3, std::nullopt, 0, "not measured: no verification point within the radius");
        settle(worst, std::nullopt, 0, "not measured: no verification point within the radius");
      } else {
        double ss = 0, w = -1, w_se = 0;
        const DwellStats* at = nullptr;
        for (const auto* d : ver_in) {
          const double e = d->mean[ax] - d->ref[ax];
          ss += e * e;
          if (std::fabs(e) > w) {
            w = std::fabs(e);
            at = d;
            w_se = d->se[ax];
          }
        }
        const double n = static_cast<double>(ver_in.size());
        const double v3 = 3.0 * std::sqrt(ss / n);
        settle(rms3, v3, v3 / std::sqrt(2.0 * n),
               fmt::format("{} verification points within {} arcmin; error = calibrated angle - reference, "
                           "mean over each dwell's frames",
                           ver_in.size(), L.accuracy_radius_arcmin.value));
        settle(worst, w, w_se,
               fmt::format("{:+.3f} arcsec at {}", at->mean[ax] - at->ref[ax], where_text(*at)));
      }
      if (ver_null.empty()) {
        settle(centre, std::nullopt, 0, "not measured: no verification null dwell");
      } else {
        double w = -1, w_se = 0;
        const DwellStats* at = nullptr;
        for (const auto* d : ver_null) {
          const double e = std::fabs(d->mean[ax] - d->ref[ax]);
          if (e > w) {
            w = e;
            at = d;
            w_se = d->se[ax];
          }
        }
        settle(centre, w, w_se,
               fmt::format("{} null dwells after the calibration; worst {:+.3f} arcsec at step {}", ver_null.size(),
                           at->mean[ax] - at->ref[ax], at->step));
      }
    }
    J.criteria.push_back(rms3);
    J.criteria.push_back(worst);
    J.criteria.push_back(centre);
  }

  // 3. Jitter at rest.
  for (int ax = 0; ax < 2; ++ax) {
    const std::string a = axis_name(ax);
    Criterion jit = make("jitter_3sigma_" + a, fmt::format("Jitter at rest, 3 sigma, {}", axis_label(ax)), a,
                         L.jitter_3sigma_arcsec, "jitter_3sigma_arcsec", "<=", "arcsec");
    if (!cal) {
      settle(jit, std::nullopt, 0, no_cal);
    } else if (rest.empty()) {
      settle(jit, std::nullopt, 0, "not measured: no rest dwell was recorded");
    } else {
      double w = -1, u = 0;
      const DwellStats* at = nullptr;
      for (const auto* d : rest) {
        const double j3 = 3.0 * d->sd_detrended[ax];
        if (j3 > w) {
          w = j3;
          at = d;
          u = d->frames > 2 ? j3 / std::sqrt(2.0 * static_cast<double>(d->frames - 2)) : j3;
        }
      }
      settle(jit, w, u,
             fmt::format("worst of {} rest dwells: {} ({} frames, linear trend removed)", rest.size(), where_text(*at),
                         at->frames));
    }
    J.criteria.push_back(jit);
  }

  // 4. Field coverage: the calibration's range and the verification's reach, per axis.
  for (int ax = 0; ax < 2; ++ax) {
    const std::string a = axis_name(ax);
    Criterion range = make("calibrated_range_" + a, fmt::format("Calibrated range, {}", axis_label(ax)), a,
                           L.calibrated_range_deg, "calibrated_range_deg", ">=", "deg");
    if (!residuals.is_object() || !residuals.contains(a) || !residuals[a].contains("range_deg") ||
        !residuals[a]["range_deg"].is_array() || residuals[a]["range_deg"].size() != 2) {
      settle(range, std::nullopt, 0, cal ? "not measured: calibration.json has no range_deg for " + a : no_cal);
    } else {
      const double lo = residuals[a]["range_deg"][0].get<double>(), hi = residuals[a]["range_deg"][1].get<double>();
      settle(range, std::min(-lo, hi), 0.0,
             fmt::format("reference angles of the calibration dwells span {:+.4f} .. {:+.4f} deg (the smaller side)", lo, hi));
    }
    J.criteria.push_back(range);

    Criterion ext = make("verified_extent_" + a, fmt::format("Verified extent, {}", axis_label(ax)), a,
                         L.verified_extent_deg, "verified_extent_deg", ">=", "deg");
    if (ver_in.empty()) {
      settle(ext, std::nullopt, 0, "not measured: no verification point within the radius");
    } else {
      double lo = 0, hi = 0;
      for (const auto* d : ver_in) {
        lo = std::min(lo, d->ref[ax]);
        hi = std::max(hi, d->ref[ax]);
      }
      settle(ext, std::min(-lo, hi) / kArcsecPerDeg, 0.0,
             fmt::format("verification points span {:+.4f} .. {:+.4f} deg (the smaller side)", lo / kArcsecPerDeg,
                         hi / kArcsecPerDeg));
    }
    J.criteria.push_back(ext);
  }
  {
    Criterion n = make("verification_points", "Verification points within the radius", "", L.verification_points_min,
                       "verification_points_min", ">=", "points");
    settle(n, static_cast<double>(ver_in.size()), 0.0,
           fmt::format("{} offset points within {} arcmin of the centre ({} verification offset points in all)",
                       ver_in.size(), L.accuracy_radius_arcmin.value, ver_off.size()));
    J.criteria.push_back(n);
  }

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
    settle(sun, std::min(frac, 1.0), 0.0, detail);
    J.criteria.push_back(sun);
  }

  // 6. Consistency with the unit's last accepted or imported calibration (only when it has one).
  if (data.previous) {
    Criterion con = make("consistency", "Change since the unit's last accepted or imported calibration (max |B - A|, +-0.35 deg)", "",
                         L.consistency_arcsec, "consistency_arcsec", "<=", "arcsec");
    if (!cal) {
      settle(con, std::nullopt, 0, no_cal);
    } else {
      try {
        const DriftCheck d = check_drift(*data.previous, *cal, L.consistency_arcsec.value);
        double u = 0;
        if (cal->extra.contains("uncertainties")) {
          const auto& un = cal->extra["uncertainties"];
          const int worst_ax = d.worst_axis == "alpha" ? 0 : 1;
          const char* key = axis_name(worst_ax);
          if (un.contains(key) && un[key].contains("angle_sigma_max_arcsec")) {
            u = un[key]["angle_sigma_max_arcsec"].get<double>();
          }
        }
        settle(con, d.worst_arcsec, u,
               fmt::format("against {}: alpha max {:.3f}, beta max {:.3f} arcsec ({:.3f} with the null shift removed)",
                           data.previous_name, d.comparison.alpha.max_abs_arcsec, d.comparison.beta.max_abs_arcsec,
                           d.worst_shape_arcsec));
      } catch (const InputError& e) {
        settle(con, std::nullopt, 0, std::string("not measured: ") + e.what());
      }
    }
    J.criteria.push_back(con);
  }

  for (const auto& d : dwells) {
    if (d.role == PointRole::calibration) continue;
    JudgedPoint p;
    p.step = d.step;
    p.role = d.role;
    p.phase = d.phase;
    p.ref_pitch_arcsec = d.ref[0];
    p.ref_yaw_arcsec = d.ref[1];
    p.frames = d.frames;
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
  J.passed = std::all_of(J.criteria.begin(), J.criteria.end(), [](const Criterion& c) { return c.passed; });
  return J;
}

// ---------------------------------------------------------------------------------------------
// Certificate

nlohmann::ordered_json certificate_json(const Judgement& j, const AcceptanceLimits& limits, const CertificateInfo& info) {
  nlohmann::ordered_json c;
  c["format"] = "fpss-stand acceptance/1";
  c["verdict"] = j.passed ? "pass" : "fail";
  c["passed"] = j.passed;
  c["unit"] = info.unit;
  c["stand"] = {{"identity", info.stand}, {"detail", info.stand_detail}};
  c["software"] = {{"name", "fpss-stand"}, {"version", info.software_version}};
  c["procedure"] = {{"name", info.procedure_name}, {"file", info.procedure_file}, {"sha256", info.procedure_sha256}};
  c["limits"] = {{"name", limits.name}, {"file", limits.origin}, {"sha256", limits.sha256}};
  c["run"] = {{"id", info.run_id},
              {"dir", info.run_dir},
              {"outcome", info.run_outcome},
              {"reason", info.run_reason},
              {"points_planned", info.points_planned},
              {"points_completed", info.points_completed}};
  c["date_utc"] = info.date_utc;
  c["calibration"] = info.calibration_file.empty() ? nlohmann::ordered_json(nullptr)
                                                   : nlohmann::ordered_json(info.calibration_file);
  nlohmann::ordered_json crit = nlohmann::ordered_json::array();
  for (const auto& k : j.criteria) {
    nlohmann::ordered_json e;
    e["id"] = k.id;
    e["title"] = k.title;
    e["axis"] = k.axis;
    e["measured"] = k.measured ? nlohmann::ordered_json(*k.measured) : nlohmann::ordered_json(nullptr);
    e["uncertainty"] = k.uncertainty;
    e["limit"] = k.limit;
    e["relation"] = k.relation;
    e["unit"] = k.unit;
    e["passed"] = k.passed;
    e["limit_key"] = k.limit_key;
    e["source"] = k.source;
    e["detail"] = k.detail;
    crit.push_back(std::move(e));
  }
  c["criteria"] = crit;
  c["failed"] = j.failed();
  nlohmann::ordered_json pts = nlohmann::ordered_json::array();
  for (const auto& p : j.points) {
    nlohmann::ordered_json e;
    e["step"] = p.step;
    e["role"] = to_string(p.role);
    e["phase"] = std::string(to_string(p.phase));
    e["ref_pitch_arcsec"] = p.ref_pitch_arcsec;
    e["ref_yaw_arcsec"] = p.ref_yaw_arcsec;
    e["frames"] = p.frames;
    e["error_pitch_arcsec"] = p.error_pitch_arcsec;
    e["error_yaw_arcsec"] = p.error_yaw_arcsec;
    e["se_pitch_arcsec"] = p.se_pitch_arcsec;
    e["se_yaw_arcsec"] = p.se_yaw_arcsec;
    if (p.role == PointRole::rest) {
      e["jitter_3sigma_pitch_arcsec"] = p.jitter3_pitch_arcsec;
      e["jitter_3sigma_yaw_arcsec"] = p.jitter3_yaw_arcsec;
    }
    pts.push_back(std::move(e));
  }
  c["points"] = pts;
  return c;
}

namespace {

std::string value_text(const nlohmann::ordered_json& k) {
  if (k["measured"].is_null()) return "not measured";
  const std::string unit = k["unit"].get<std::string>();
  const double v = k["measured"].get<double>(), u = k["uncertainty"].get<double>();
  const int dec = unit == "points" ? 0 : unit == "deg" ? 4 : 3;
  if (u > 0) return fmt::format("{:.{}f} +- {:.{}f}", v, dec, u, dec);
  return fmt::format("{:.{}f}", v, dec);
}

std::string limit_text(const nlohmann::ordered_json& k) {
  const std::string unit = k["unit"].get<std::string>();
  const int dec = unit == "points" ? 0 : unit == "deg" ? 2 : unit == "fraction" ? 2 : 1;
  return fmt::format("{} {:.{}f}", k["relation"].get<std::string>(), k["limit"].get<double>(), dec);
}

}  // namespace

std::string certificate_text(const nlohmann::ordered_json& c) {
  std::string s;
  s += "FPSS UNIT ACCEPTANCE CERTIFICATE\n\n";
  s += fmt::format("Verdict:    {}\n", c["passed"].get<bool>() ? "PASS" : "FAIL");
  s += fmt::format("Unit:       {}\n", c["unit"].get<std::string>());
  s += fmt::format("Stand:      {}\n", c["stand"]["identity"].get<std::string>());
  s += fmt::format("Software:   fpss-stand {}\n", c["software"]["version"].get<std::string>());
  s += fmt::format("Procedure:  {} ({}), sha256 {}\n", c["procedure"]["name"].get<std::string>(),
                   c["procedure"]["file"].get<std::string>(), c["procedure"]["sha256"].get<std::string>());
  s += fmt::format("Limits:     {} ({}), sha256 {}\n", c["limits"]["name"].get<std::string>(),
                   c["limits"]["file"].get<std::string>(), c["limits"]["sha256"].get<std::string>());
  s += fmt::format("Run:        {} ({}, {}/{} points)\n", c["run"]["id"].get<std::string>(),
                   c["run"]["outcome"].get<std::string>(), c["run"]["points_completed"].get<int64_t>(),
                   c["run"]["points_planned"].get<int64_t>());
  if (!c["run"]["reason"].get<std::string>().empty()) {
    s += fmt::format("            stopped: {}\n", c["run"]["reason"].get<std::string>());
  }
  s += fmt::format("Date (UTC): {}\n\n", c["date_utc"].get<std::string>());
  s += fmt::format("{:<28} {:>22} {:>10} {:<8} {}\n", "criterion", "measured (+- 1 sigma)", "limit", "unit", "result");
  for (const auto& k : c["criteria"]) {
    s += fmt::format("{:<28} {:>22} {:>10} {:<8} {}\n", k["id"].get<std::string>(), value_text(k), limit_text(k),
                     k["unit"].get<std::string>(), k["passed"].get<bool>() ? "pass" : "FAIL");
  }
  s += "\nHow each was measured and where its limit comes from:\n";
  for (const auto& k : c["criteria"]) {
    s += fmt::format("- {}: {}\n    limit: {}\n", k["id"].get<std::string>(), k["detail"].get<std::string>(),
                     k["source"].get<std::string>());
  }
  return s;
}

std::string certificate_html(const nlohmann::ordered_json& c) {
  const bool pass = c["passed"].get<bool>();
  std::string h;
  h += fmt::format("<p class=\"verdict\" style=\"font-size:1.3em;font-weight:bold;color:{}\">Acceptance: {}</p>\n",
                   pass ? "#1a7f37" : "#b42318", pass ? "PASS" : "FAIL");
  h += "<table>\n";
  auto row = [&](const char* k, const std::string& v) {
    h += fmt::format("<tr><th style=\"text-align:left\">{}</th><td>{}</td></tr>\n", k, html_escape(v));
  };
  row("Unit", c["unit"].get<std::string>());
  row("Stand", c["stand"]["identity"].get<std::string>());
  row("Software", "fpss-stand " + c["software"]["version"].get<std::string>());
  row("Procedure", fmt::format("{} ({}), sha256 {}", c["procedure"]["name"].get<std::string>(),
                               c["procedure"]["file"].get<std::string>(), c["procedure"]["sha256"].get<std::string>()));
  row("Limits", fmt::format("{} ({}), sha256 {}", c["limits"]["name"].get<std::string>(),
                            c["limits"]["file"].get<std::string>(), c["limits"]["sha256"].get<std::string>()));
  row("Run", fmt::format("{} ({}, {}/{} points){}", c["run"]["id"].get<std::string>(),
                         c["run"]["outcome"].get<std::string>(), c["run"]["points_completed"].get<int64_t>(),
                         c["run"]["points_planned"].get<int64_t>(),
                         c["run"]["reason"].get<std::string>().empty() ? "" : ": " + c["run"]["reason"].get<std::string>()));
  row("Date (UTC)", c["date_utc"].get<std::string>());
  h += "</table>\n<h3>Criteria</h3>\n<table class=\"criteria\">\n";
  h += "<tr><th>criterion</th><th>measured (&plusmn; 1&sigma;)</th><th>limit</th><th>unit</th><th>result</th>"
       "<th>how measured</th><th>source of the limit</th></tr>\n";
  for (const auto& k : c["criteria"]) {
    const bool ok = k["passed"].get<bool>();
    h += fmt::format(
        "<tr><td title=\"{}\">{}</td><td>{}</td><td>{}</td><td>{}</td><td style=\"font-weight:bold;color:{}\">{}</td>"
        "<td>{}</td><td>{}</td></tr>\n",
        html_escape(k["title"].get<std::string>()), html_escape(k["id"].get<std::string>()), html_escape(value_text(k)),
        html_escape(limit_text(k)), html_escape(k["unit"].get<std::string>()), ok ? "#1a7f37" : "#b42318",
        ok ? "pass" : "FAIL", html_escape(k["detail"].get<std::string>()), html_escape(k["source"].get<std::string>()));
  }
  h += "</table>\n<h3>Verification and rest points</h3>\n<table class=\"points\">\n";
  h += "<tr><th>step</th><th>role</th><th>pitch (deg)</th><th>yaw (deg)</th><th>frames</th>"
       "<th>error pitch (arcsec)</th><th>error yaw (arcsec)</th><th>jitter 3&sigma; pitch</th><th>jitter 3&sigma; yaw</th></tr>\n";
  for (const auto& p : c["points"]) {
    const bool rest = p["role"] == "rest";
    h += fmt::format("<tr><td>{}</td><td>{}{}</td><td>{:+.4f}</td><td>{:+.4f}</td><td>{}</td><td>{:+.3f}</td><td>{:+.3f}</td>"
                     "<td>{}</td><td>{}</td></tr>\n",
                     p["step"].get<int64_t>(), p["role"].get<std::string>(),
                     p["phase"] == "null" && !rest ? " (null)" : "", p["ref_pitch_arcsec"].get<double>() / 3600.0,
                     p["ref_yaw_arcsec"].get<double>() / 3600.0, p["frames"].get<int64_t>(),
                     p["error_pitch_arcsec"].get<double>(), p["error_yaw_arcsec"].get<double>(),
                     rest ? fmt::format("{:.3f}", p["jitter_3sigma_pitch_arcsec"].get<double>()) : "",
                     rest ? fmt::format("{:.3f}", p["jitter_3sigma_yaw_arcsec"].get<double>()) : "");
  }
  h += "</table>\n";
  return h;
}

}  // namespace fpss
