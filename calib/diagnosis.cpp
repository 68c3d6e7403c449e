// The diagnosis: noise floor, observability, every candidate fitted on the fit steps and scored
// on the held-out steps, a second effect when the first leaves a gap, and where the gap lies.
#include "calib/diagnosis.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "calib/diagnosis_model.h"
#include "calib/errors.h"

namespace fpss {

using ojson = nlohmann::ordered_json;
using diag::Candidate;
using diag::Contribution;
using diag::Recording;
using diag::StepKind;
using diag::Use;

const std::vector<std::string>& diagnosis_effect_names() {
  static const std::vector<std::string> k = {"bias",     "drift",    "scale_factor", "boresight_roll", "axis_nonorthogonality",
                                             "backlash", "settling", "time_skew",    "coefficients",   "temperature"};
  return k;
}

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Mean square over both axes of (residual - contribution) on `rows`.
double mean_square(const Recording& r, const Contribution* c, const std::vector<uint32_t>& rows) {
  double s = 0;
  for (uint32_t i : rows) {
    for (int a = 0; a < 2; ++a) {
      const double e = r.res[a][i] - (c ? c->v[a][i] : 0.0);
      s += e * e;
    }
  }
  return rows.empty() ? 0.0 : s / (2.0 * static_cast<double>(rows.size()));
}

// Measurement noise from within-step scatter: second differences of the residual between
// consecutive rows of a dwell (var = 6 sigma^2 for white noise; smooth effects such as settling,
// drift or temperature nearly cancel), clipped at 4 sigma to drop the odd step change.
double noise_floor(const Recording& r, double* per_axis) {
  auto estimate = [&](StepKind kind, int a, size_t* used) {
    std::vector<double> d2;
    for (const auto& s : r.steps) {
      if (s.kind != kind) continue;
      for (size_t i = s.begin + 1; i + 1 < s.end; ++i) {
        const double d = r.res[a][i + 1] - 2 * r.res[a][i] + r.res[a][i - 1];
        d2.push_back(d * d);
      }
    }
    *used = d2.size();
    if (d2.empty()) return kNaN;
    double ms = std::accumulate(d2.begin(), d2.end(), 0.0) / static_cast<double>(d2.size());
    for (int it = 0; it < 3; ++it) {
      const double lim = 16.0 * ms;
      double s = 0;
      size_t m = 0;
      for (double v : d2) if (v <= lim) { s += v; ++m; }
      if (m == 0) break;
      ms = s / static_cast<double>(m);
    }
    return std::sqrt(ms / 6.0);
  };
  double sig[2];
  for (int a = 0; a < 2; ++a) {
    size_t used = 0;
    sig[a] = estimate(StepKind::dwell, a, &used);
    if (used < 10) {
      size_t m = 0;
      const double s2 = estimate(StepKind::motion, a, &m);
      if (m > used) sig[a] = s2;
    }
    if (per_axis) per_axis[a] = sig[a];
  }
  return std::sqrt(0.5 * (sig[0] * sig[0] + sig[1] * sig[1]));
}

struct Observability {
  std::vector<NotObservable> missing;
  bool ok(const std::string& name) const {
    return std::none_of(missing.begin(), missing.end(), [&](const NotObservable& m) { return m.name == name; });
  }
};

Observability observability(const Recording& r) {
  Observability o;
  auto add = [&](std::string name, std::string reason, bool incomplete) {
    o.missing.push_back({std::move(name), std::move(reason), incomplete});
  };
  // Angles covered at rest (offsets), per axis.
  double span[2];
  for (int a = 0; a < 2; ++a) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const auto& s : r.steps) {
      if (s.kind != StepKind::dwell) continue;
      for (size_t i = s.begin; i < s.end; ++i) { lo = std::min(lo, r.ref[a][i]); hi = std::max(hi, r.ref[a][i]); }
    }
    span[a] = hi - lo;
  }
  constexpr double kMinSpan = 60.0;  // arcsec
  if (span[0] < kMinSpan && span[1] < kMinSpan) {
    const std::string why = fmt::format(
        "no offsets: every dwell lies within {:.0f} arcsec of one position on both axes, so an angle-proportional "
        "error cannot be told apart from a bias; record null-offset steps on both axes",
        std::max(span[0], span[1]));
    for (const char* e : {"scale_factor", "boresight_roll", "axis_nonorthogonality", "coefficients"}) add(e, why, true);
  } else {
    if (span[0] < kMinSpan) {
      add("axis_nonorthogonality", "no pitch offsets: the yaw error proportional to pitch cannot be seen", true);
    }
    if (span[0] < kMinSpan || span[1] < kMinSpan) {
      add("boresight_roll",
          fmt::format("no {} offsets: a roll cannot be told apart from axis_nonorthogonality or a scale factor",
                      span[0] < kMinSpan ? "pitch" : "yaw"),
          true);
    }
  }
  // Motion while sampling.
  size_t moving = 0;
  for (size_t i = 0; i < r.n; ++i) {
    if (r.use[i] != Use::excluded && (std::abs(r.vel[0][i]) > 5.0 || std::abs(r.vel[1][i]) > 5.0)) ++moving;
  }
  if (moving < 20) {
    add("time_skew",
        "no motion while sampling (no slew rows away from the segment ends): a shift between the sensor's and the "
        "reference's sampling times changes nothing at rest, so it cannot be seen; record continuous slews",
        true);
  }
  // Approach from both sides.
  size_t plus = 0, minus = 0;
  for (uint32_t i : r.fit_rows) for (int a = 0; a < 2; ++a) { plus += r.dir[a][i] > 0; minus += r.dir[a][i] < 0; }
  if (plus < 5 || minus < 5) add("backlash", "every position was approached from the same side: backlash acts as a bias", false);
  // Dwells after moves with a clock since arrival.
  size_t settled = 0;
  double tmin = std::numeric_limits<double>::infinity(), tmax = -tmin;
  for (uint32_t i : r.fit_rows) {
    if (!std::isfinite(r.since_move[i]) || (r.move_dir[0][i] == 0 && r.move_dir[1][i] == 0)) continue;
    ++settled;
    tmin = std::min(tmin, r.since_move[i]);
    tmax = std::max(tmax, r.since_move[i]);
  }
  if (settled < 10 || !(tmax - tmin > 0.02)) {
    add("settling", "no dwell samples spread in time after a move: a decay after arrival cannot be seen", false);
  }
  // Temperature: present, varying, and not a linear function of time (else it is drift).
  if (!r.has_temperature) {
    add("temperature", "the recording has no temperature_c column", false);
  } else {
    double n = 0, st = 0, sT = 0, stt = 0, sTT = 0, stT = 0, lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (size_t i = 0; i < r.n; ++i) {
      const double T = r.temp[i];
      if (!std::isfinite(T)) continue;
      n += 1; st += r.t[i]; sT += T; stt += r.t[i] * r.t[i]; sTT += T * T; stT += r.t[i] * T;
      lo = std::min(lo, T); hi = std::max(hi, T);
    }
    const double vt = stt - st * st / n, vT = sTT - sT * sT / n, c = stT - st * sT / n;
    const double rho = vt > 0 && vT > 0 ? c / std::sqrt(vt * vT) : 0.0;
    if (!(hi - lo >= 0.05)) {
      add("temperature", fmt::format("temperature_c varies by only {:.3f} C", hi - lo), false);
    } else if (std::abs(rho) > 0.995) {
      add("temperature",
          fmt::format("temperature_c follows time linearly (correlation {:.4f}): a temperature coefficient cannot be "
                      "told apart from drift, which stands for both; vary the temperature non-monotonically",
                      rho),
          false);
    }
  }
  return o;
}

struct Scored {
  std::unique_ptr<Candidate> cand;
  Contribution contrib;
  EffectResult result;
};

double penalised(double ms, double ms0, int k, double N) {
  if (ms0 <= 0) return k * std::log(N);
  return N * std::log(std::max(ms, 1e-300) / ms0) + k * std::log(N);
}

Scored fit_one(const Recording& r, const std::string& name, const Contribution& target, double ms0, double N) {
  Scored s;
  s.cand = diag::make_candidate(name);
  s.cand->fit(r, target, r.fit_rows);
  s.contrib.resize(r.n);
  s.cand->contribute(r, s.contrib);
  s.result.name = name;
  s.result.params = s.cand->params();
  s.result.parameters = s.cand->parameters();
  s.result.fit_rms_arcsec = std::sqrt(mean_square(r, &s.contrib, r.fit_rows));
  const double ms = mean_square(r, &s.contrib, r.heldout_rows);
  s.result.heldout_rms_arcsec = std::sqrt(ms);
  s.result.score = penalised(ms, ms0, s.result.parameters, N);
  s.result.notes = s.cand->notes();
  return s;
}

// ------------------------------------------------------------------ where

struct FactorValues {
  const char* name;
  std::vector<double> x[2];  // per axis; NaN rows form their own group
  int bins;
  const char* unit;
  const char* nan_label;
  bool discrete = false;
};

std::string signed_num(double v, int prec = 2) { return fmt::format("{:+.{}f}", v, prec); }

struct BinStats {
  std::vector<double> sum, n;  // bins + 1 (last: NaN group)
};

int bin_of(double x, double lo, double hi, int bins) {
  if (!std::isfinite(x)) return bins;
  if (hi <= lo) return 0;
  return std::clamp(static_cast<int>((x - lo) / (hi - lo) * bins), 0, bins - 1);
}

std::vector<WhereEntry> where_of(const Recording& r, const std::vector<double> e_in[2]) {
  const std::vector<uint32_t>& F = r.fit_rows;
  const std::vector<uint32_t>& H = r.heldout_rows;
  double total = 0;
  for (uint32_t i : H) total += e_in[0][i] * e_in[0][i] + e_in[1][i] * e_in[1][i];
  std::vector<WhereEntry> out;
  if (total <= 0) return out;
  const char* axis_name[2] = {"pitch", "yaw"};

  // constant
  double mean[2];
  std::vector<WhereEntry> per_axis;
  for (int a = 0; a < 2; ++a) {
    double s = 0;
    for (uint32_t i : F) s += e_in[a][i];
    mean[a] = F.empty() ? 0 : s / static_cast<double>(F.size());
    double before = 0, after = 0;
    for (uint32_t i : H) { before += e_in[a][i] * e_in[a][i]; after += (e_in[a][i] - mean[a]) * (e_in[a][i] - mean[a]); }
    per_axis.push_back({"constant", axis_name[a], std::max(0.0, before - after) / total,
                        fmt::format("mean residual {} arcsec", signed_num(mean[a]))});
  }

  std::vector<FactorValues> factors;
  auto add_factor = [&](const char* name, int bins, const char* unit, const char* nan_label, auto&& value, bool discrete = false) {
    FactorValues f{name, {}, bins, unit, nan_label, discrete};
    for (int a = 0; a < 2; ++a) {
      f.x[a].resize(r.n);
      for (size_t i = 0; i < r.n; ++i) f.x[a][i] = value(i, a);
    }
    factors.push_back(std::move(f));
  };
  add_factor("angle", 12, "arcsec", "", [&](size_t i, int a) { return r.ref[a][i]; });
  add_factor("cross_angle", 12, "arcsec", "", [&](size_t i, int a) { return r.ref[1 - a][i]; });
  add_factor("slew_rate", 8, "arcsec/s", "at rest", [&](size_t i, int a) {
    return r.steps[r.step_of[i]].kind == StepKind::motion && std::abs(r.vel[a][i]) > 1.0 ? r.vel[a][i] : kNaN;
  });
  add_factor("approach_direction", 3, "", "", [&](size_t i, int a) { return static_cast<double>(r.dir[a][i]); }, true);
  add_factor("time", 10, "s", "", [&](size_t i, int) { return r.t[i]; });
  add_factor("time_since_move", 8, "s", "while moving", [&](size_t i, int) { return r.since_move[i]; });
  if (r.has_temperature) add_factor("temperature", 10, "C", "no reading", [&](size_t i, int) { return r.temp[i]; });

  for (const auto& f : factors) {
    for (int a = 0; a < 2; ++a) {
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (uint32_t i : F) if (std::isfinite(f.x[a][i])) { lo = std::min(lo, f.x[a][i]); hi = std::max(hi, f.x[a][i]); }
      for (uint32_t i : H) if (std::isfinite(f.x[a][i])) { lo = std::min(lo, f.x[a][i]); hi = std::max(hi, f.x[a][i]); }
      if (f.discrete) { lo = -1.5; hi = 1.5; }
      const int nb = f.bins;
      std::vector<double> sum(nb + 1, 0.0), cnt(nb + 1, 0.0);
      for (uint32_t i : F) {
        const int b = bin_of(f.x[a][i], lo, hi, nb);
        sum[b] += e_in[a][i] - mean[a];
        cnt[b] += 1;
      }
      double before = 0, after = 0;
      for (uint32_t i : H) {
        const int b = bin_of(f.x[a][i], lo, hi, nb);
        const double e = e_in[a][i] - mean[a];
        const double pred = cnt[b] >= 3 ? sum[b] / cnt[b] : 0.0;
        before += e * e;
        after += (e - pred) * (e - pred);
      }
      // Words: the bins (all scored rows) with the largest positive and negative means.
      std::vector<double> s2(nb + 1, 0.0), c2(nb + 1, 0.0);
      for (size_t i = 0; i < r.n; ++i) {
        if (r.use[i] == Use::excluded) continue;
        const int b = bin_of(f.x[a][i], lo, hi, nb);
        s2[b] += e_in[a][i];
        c2[b] += 1;
      }
      auto label = [&](int b) -> std::string {
        if (b == nb) return f.nan_label;
        if (f.discrete) {
          const int d = b - 1;
          return d == 0 ? "before any move of this axis" : (d > 0 ? "after motion in +" : "after motion in -");
        }
        const double w = (hi - lo) / nb;
        const std::string fn = f.name;
        const std::string what = fn == "angle"         ? std::string(axis_name[a])
                                 : fn == "cross_angle" ? std::string(axis_name[1 - a])
                                 : fn == "slew_rate"   ? std::string(axis_name[a]) + " rate"
                                                       : fn;
        return fmt::format("{} {:.4g}..{:.4g} {}", what, lo + b * w, lo + (b + 1) * w, f.unit);
      };
      int bmax = -1, bmin = -1;
      for (int b = 0; b <= nb; ++b) {
        if (c2[b] < 3) continue;
        const double m = s2[b] / c2[b];
        if (bmax < 0 || m > s2[bmax] / c2[bmax]) bmax = b;
        if (bmin < 0 || m < s2[bmin] / c2[bmin]) bmin = b;
      }
      std::string detail;
      if (bmax >= 0) {
        detail = fmt::format("mean residual {} arcsec at {}, {} at {}", signed_num(s2[bmax] / c2[bmax]), label(bmax),
                             signed_num(s2[bmin] / c2[bmin]), label(bmin));
      }
      per_axis.push_back({f.name, axis_name[a], std::max(0.0, before - after) / total, detail});
    }
  }
  // Merge a factor's two axes when both carry a comparable part.
  for (size_t k = 0; k + 1 < per_axis.size(); k += 2) {
    const WhereEntry& p = per_axis[k];
    const WhereEntry& y = per_axis[k + 1];
    const double hi = std::max(p.share, y.share), lo = std::min(p.share, y.share);
    if (lo >= 0.01 && lo >= 0.25 * hi) {
      out.push_back({p.factor, "both", p.share + y.share, fmt::format("pitch: {}; yaw: {}", p.detail, y.detail)});
    } else {
      out.push_back(p.share >= y.share ? p : y);
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const WhereEntry& a, const WhereEntry& b) { return a.share > b.share; });
  std::vector<WhereEntry> kept;
  for (const auto& w : out) if (w.share >= 0.01 || kept.size() < 3) kept.push_back(w);
  return kept;
}

ojson where_json(const std::vector<WhereEntry>& w) {
  ojson a = ojson::array();
  for (const auto& e : w) a.push_back({{"factor", e.factor}, {"axis", e.axis}, {"share", e.share}, {"detail", e.detail}});
  return a;
}

ojson effect_json(const EffectResult& e) {
  ojson j{{"name", e.name}, {"params", e.params}, {"parameters", e.parameters}, {"fit_rms_arcsec", e.fit_rms_arcsec},
          {"heldout_rms_arcsec", e.heldout_rms_arcsec}, {"score", e.score}};
  if (!e.notes.empty()) j["notes"] = e.notes;
  return j;
}

}  // namespace

bool Diagnosis::incomplete_recording() const {
  return std::any_of(not_observable.begin(), not_observable.end(), [](const NotObservable& n) { return n.incomplete_recording; });
}

ojson Diagnosis::to_json() const {
  ojson j;
  j["source"] = source;
  j["cause"] = cause;
  ojson cs = ojson::array();
  for (const auto& c : causes) cs.push_back(effect_json(c));
  j["causes"] = cs;
  j["gap_before_arcsec"] = gap_before_arcsec;
  j["gap_after_arcsec"] = gap_after_arcsec;
  j["gap_after_all_arcsec"] = gap_after_all_arcsec;
  j["noise_floor_arcsec"] = noise_floor_arcsec;
  j["where"] = where_json(where);
  j["where_after"] = where_json(where_after);
  ojson ef = ojson::array();
  for (const auto& e : effects) ef.push_back(effect_json(e));
  j["effects"] = ef;
  j["selection"] = {
      {"score", "N ln(MSE / MSE_none) + k ln N on the held-out rows: N = 2 x held-out rows (both axes), MSE the "
                "held-out mean square of residual - effect, k the effect's free parameters; lower is better, none = 0"},
      {"second_effect", "fitted jointly with the first (alternating least squares) when the first leaves more than "
                        "1.2x the noise floor; kept when its joint score beats the first alone"}};
  ojson no = ojson::array();
  for (const auto& n : not_observable) {
    no.push_back({{"name", n.name}, {"reason", n.reason}, {"incomplete_recording", n.incomplete_recording}});
  }
  j["not_observable"] = no;
  j["split"] = split;
  j["recording"] = recording;
  j["warnings"] = warnings;
  return j;
}

Diagnosis diagnose(const SampleTable& data, const CoefficientSet& model, const DiagnosisOptions& opts) {
  const Recording r = diag::prepare(data, model, opts);
  Diagnosis d;
  d.source = r.origin;
  double sig[2];
  d.noise_floor_arcsec = noise_floor(r, sig);
  const Observability obs = observability(r);
  d.not_observable = obs.missing;

  const double N = 2.0 * static_cast<double>(r.heldout_rows.size());
  const double ms0 = mean_square(r, nullptr, r.heldout_rows);
  d.gap_before_arcsec = std::sqrt(ms0);
  Contribution target;
  for (int a = 0; a < 2; ++a) target.v[a] = r.res[a];

  std::vector<Scored> all;
  {
    Scored none;
    none.result.name = "none";
    none.result.params = ojson::object();
    none.result.fit_rms_arcsec = std::sqrt(mean_square(r, nullptr, r.fit_rows));
    none.result.heldout_rms_arcsec = d.gap_before_arcsec;
    none.result.score = 0;
    none.contrib.resize(r.n);
    all.push_back(std::move(none));
  }
  for (const auto& name : diagnosis_effect_names()) {
    if (!obs.ok(name)) continue;
    all.push_back(fit_one(r, name, target, ms0, N));
  }
  std::stable_sort(all.begin(), all.end(), [](const Scored& a, const Scored& b) { return a.result.score < b.result.score; });
  for (const auto& s : all) d.effects.push_back(s.result);

  const Scored& best = all.front();
  d.cause = best.result.name;
  d.gap_after_arcsec = best.result.heldout_rms_arcsec;
  d.gap_after_all_arcsec = d.gap_after_arcsec;
  Contribution combined;
  combined.resize(r.n);
  if (d.cause != "none") {
    EffectResult first = best.result;
    combined = best.contrib;
    // A second effect, fitted jointly with the first, when the first leaves a gap above noise.
    if (opts.second_effect && d.gap_after_arcsec > opts.second_effect_gap_ratio * d.noise_floor_arcsec) {
      double best_score = best.result.score;
      std::optional<std::pair<EffectResult, EffectResult>> pick;
      Contribution pick_contrib;
      for (const auto& s : all) {
        const std::string& name2 = s.result.name;
        if (name2 == "none" || name2 == d.cause) continue;
        auto c1 = diag::make_candidate(d.cause);
        auto c2 = diag::make_candidate(name2);
        Contribution k1 = best.contrib, k2, t;
        k2.resize(r.n);
        t.resize(r.n);
        for (int it = 0; it < 4; ++it) {
          for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) t.v[a][i] = r.res[a][i] - k1.v[a][i];
          c2->fit(r, t, r.fit_rows);
          c2->contribute(r, k2);
          for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) t.v[a][i] = r.res[a][i] - k2.v[a][i];
          c1->fit(r, t, r.fit_rows);
          c1->contribute(r, k1);
        }
        Contribution sum;
        sum.resize(r.n);
        for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) sum.v[a][i] = k1.v[a][i] + k2.v[a][i];
        const double ms = mean_square(r, &sum, r.heldout_rows);
        const int k = c1->parameters() + c2->parameters();
        const double score = penalised(ms, ms0, k, N);
        if (score < best_score) {
          best_score = score;
          EffectResult e1 = first, e2;
          e1.params = c1->params();
          e1.notes = c1->notes();
          e2.name = name2;
          e2.params = c2->params();
          e2.parameters = c2->parameters();
          e2.notes = c2->notes();
          e2.fit_rms_arcsec = std::sqrt(mean_square(r, &sum, r.fit_rows));
          e2.heldout_rms_arcsec = std::sqrt(ms);
          e2.score = score;
          pick = std::make_pair(e1, e2);
          pick_contrib = sum;
        }
      }
      if (pick) {
        d.causes = {pick->first, pick->second};
        d.gap_after_all_arcsec = pick->second.heldout_rms_arcsec;
        combined = pick_contrib;
      }
    }
    if (d.causes.empty()) d.causes = {first};
  }

  std::vector<double> before[2], after[2];
  for (int a = 0; a < 2; ++a) {
    before[a] = r.res[a];
    after[a].resize(r.n);
    for (size_t i = 0; i < r.n; ++i) after[a][i] = r.res[a][i] - combined.v[a][i];
  }
  d.where = where_of(r, before);
  d.where_after = where_of(r, after);

  // What the data holds and how it was divided.
  std::vector<int64_t> held_ids;
  size_t held_d = 0, held_m = 0;
  for (const auto& s : r.steps) {
    if (!s.heldout) continue;
    held_ids.push_back(s.id);
    (s.kind == StepKind::dwell ? held_d : held_m)++;
  }
  d.split = {
      {"method", fmt::format("by whole steps: of the dwells and of the slew segments, each in its own order, every "
                             "{}th step is held out (a kind with two steps gives one to each side); rows are never "
                             "split within a step",
                             opts.heldout_every)},
      {"fit_rows", r.fit_rows.size()},
      {"heldout_rows", r.heldout_rows.size()},
      {"excluded_rows", r.excluded_rows},
      {"excluded_why", fmt::format("the first and last {} s of every slew segment (the reference outside a segment "
                                   "is not recorded, so a time shift cannot be predicted there)",
                                   r.guard_s)},
      {"fit_steps", {{"dwells", r.dwells - held_d}, {"slews", r.motions - held_m}}},
      {"heldout_steps", {{"dwells", held_d}, {"slews", held_m}}},
      {"heldout_step_ids", held_ids}};
  double t_lo = r.t.front(), t_hi = r.t.back();
  d.recording = {{"rows", r.n},
                 {"steps", r.steps.size()},
                 {"dwells", r.dwells},
                 {"slew_segments", r.motions},
                 {"time_span_s", {t_lo, t_hi}},
                 {"noise_floor_per_axis_arcsec", {{"pitch", sig[0]}, {"yaw", sig[1]}}},
                 {"temperature_c", r.has_temperature},
                 {"settle_s", opts.settle_s}};
  if (!data.has_column("time_since_move_s")) {
    d.warnings.push_back(fmt::format(
        "no time_since_move_s column: dwells are taken to start {} s after their arrival (settle_s); settling "
        "amplitudes refer to that arrival",
        opts.settle_s));
  }
  for (const auto& n : d.not_observable) {
    d.warnings.push_back(fmt::format("{} is not observable in this recording: {}", n.name, n.reason));
  }
  return d;
}

SensorPrediction predict_sensor(const SampleTable& data, const CoefficientSet& model, const EffectParams& effect,
                                const DiagnosisOptions& opts) {
  const Recording r = diag::prepare(data, model, opts);
  SensorPrediction p;
  p.pitch_arcsec.resize(r.n);
  p.yaw_arcsec.resize(r.n);
  p.predictable.assign(r.n, true);
  for (size_t i = 0; i < r.n; ++i) p.predictable[i] = r.use[i] != Use::excluded;
  if (effect.name == "coefficients") {
    if (!effect.coefficients) throw InputError("predict_sensor: the coefficients effect needs a coefficient set");
    // The sensor's counts come from the effect's transfer function; the model maps them back.
    const AxisModel truth[2] = {effect.coefficients->alpha_model(), effect.coefficients->beta_model()};
    const AxisModel m[2] = {model.alpha_model(), model.beta_model()};
    for (int a = 0; a < 2; ++a) {
      truth[a].check_monotonic();
      auto& out = a == 0 ? p.pitch_arcsec : p.yaw_arcsec;
      for (size_t i = 0; i < r.n; ++i) {
        try {
          out[i] = m[a].angle_arcsec(truth[a].counts_for_angle_unchecked(arcsec_to_rad(r.ref[a][i])));
        } catch (const std::out_of_range&) {
          out[i] = kNaN;
          p.predictable[i] = false;
        }
      }
    }
    return p;
  }
  auto c = diag::make_candidate(effect.name);
  if (!c) throw InputError(fmt::format("predict_sensor: unknown effect \"{}\"", effect.name));
  c->set(effect);
  Contribution k;
  k.resize(r.n);
  c->contribute(r, k);
  for (size_t i = 0; i < r.n; ++i) {
    p.pitch_arcsec[i] = r.ref[0][i] + k.v[0][i];
    p.yaw_arcsec[i] = r.ref[1][i] + k.v[1][i];
  }
  return p;
}

}  // namespace fpss
