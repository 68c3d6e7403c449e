// Within-step scatter, detection limits and the verdict with its remainder.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "calib/diagnosis/internal.h"

namespace fpss::diag {
namespace {

using ojson = nlohmann::ordered_json;


}  // namespace

double within_step_scatter(const Recording& r, const std::vector<float> e[2]) {
  double ss[2] = {0, 0};
  double dof = 0;
  for (const auto& s : r.steps) {
    if (s.kind != StepKind::dwell) continue;
    double sum[2] = {0, 0}, sq[2] = {0, 0}, m = 0;
    for (size_t i = s.begin; i < s.end; ++i) {
      if (r.outlier[i] || near_move(r, i)) continue;
      m += 1;
      for (int a = 0; a < 2; ++a) { sum[a] += e[a][i]; sq[a] += e[a][i] * e[a][i]; }
    }
    if (m < 3) continue;
    for (int a = 0; a < 2; ++a) ss[a] += sq[a] - sum[a] * sum[a] / m;
    dof += m - 1;
  }
  if (dof < 10) return kNaN;
  return std::sqrt(0.5 * (ss[0] + ss[1]) / dof);
}

// The smallest magnitude of each of a candidate's parameters that this recording would have made
// material: an effect of magnitude m adds m^2 G to the held-out mean square (G the mean square of
// its contribution per unit, both axes); the candidate is found when that beats both the
// materiality rule (0.1 noise^2) and the score's penalty (N ln(1 + m^2 G / noise^2) > k ln N).
// Nonlinear parameters (settling's tau, temperature's t0_c) are held at the fitted values;
// magnitudes are taken small, where every effect is linear in them.
ojson detection_limit(const Recording& r, const EffectResult& e, double noise, double N) {
  return limit_for(r, e, noise, N, noise * noise * std::max(0.1, std::expm1(e.parameters * std::log(N) / N)));
}

// The statistical limit: the magnitude whose expected held-out score equals none's, N ln(1 + m^2 G
// / noise^2) = k ln N, without the naming rule's floor of 0.1 noise^2: what the data can see, not
// what the diagnosis names. An effect at its limit scores better than none in half the recordings,
// at twice it (four times the score) in nearly all; the ambiguity margin is for telling two
// candidates apart, not one from none.
// Settling's at a time constant of 0.5 s whatever its fit says: a settling that is not there fits
// the noise with any tau, and the bound is stated for one (docs/diagnosis.md).
ojson statistical_limit(const Recording& r, const EffectResult& e, double noise, double N, double* acting_rms_arcsec) {
  EffectResult at = e;
  if (at.name == "settling") at.params["tau_s"] = kSettlingLimitTau_s;
  return limit_for(r, at, noise, N, noise * noise * std::expm1(at.parameters * std::log(N) / N), acting_rms_arcsec);
}

ojson limit_for(const Recording& r, const EffectResult& e, double noise, double N, double need,
                double* acting_rms_arcsec) {
  ojson out = ojson::object();
  if (acting_rms_arcsec) *acting_rms_arcsec = std::numeric_limits<double>::infinity();
  if (e.name == "none" || !std::isfinite(noise) || noise <= 0 || !(N > 1)) return out;
  if (e.name == "coefficients") {
    // A change of the transfer function, in arcsec: the RMS change of the angle over the
    // calibrated range that would have been material on these held-out rows, for a change of even
    // size over the range (an angle offset or slope, an ageing sinusoid over its periods), whose
    // held-out mean square is its mean square over the range. Its 16 parameters raise it on a
    // short recording (the k ln N penalty); a change confined to angles the held-out rows never
    // reach is not seen at any size.
    out["angle_rms_arcsec"] = std::sqrt(need);
    if (acting_rms_arcsec) *acting_rms_arcsec = std::sqrt(need);
    return out;
  }
  double acting = 0;  // the worst key's
  static const std::map<std::string, double> unit = {
      {"pitch_arcsec", 0.01},         {"yaw_arcsec", 0.01},         {"pitch_arcsec_per_s", 1e-5},
      {"yaw_arcsec_per_s", 1e-5},     {"pitch_ppm", 1.0},           {"yaw_ppm", 1.0},
      {"roll_arcsec", 0.1},           {"skew_arcsec", 0.1},         {"width_arcsec", 0.01},
      {"amplitude_arcsec", 0.01},     {"skew_s", 1e-5},             {"pitch_arcsec_per_c", 0.001},
      {"yaw_arcsec_per_c", 0.001}};
  for (auto it = e.params.begin(); it != e.params.end(); ++it) {
    auto u = unit.find(it.key());
    if (u == unit.end()) continue;
    EffectParams p;
    p.name = e.name;
    for (auto jt = e.params.begin(); jt != e.params.end(); ++jt) {
      if (jt.value().is_number()) p.params[jt.key()] = unit.count(jt.key()) ? 0.0 : jt.value().get<double>();
    }
    if (e.name == "settling" && !(p.params["tau_s"] > 0.02 && p.params["tau_s"] < 29)) p.params["tau_s"] = 0.5;
    if (e.name == "temperature") {
      double s = 0, m = 0;
      for (size_t i = 0; i < r.n; ++i) if (std::isfinite(r.temp[i])) { s += r.temp[i]; m += 1; }
      if (m > 0) p.params["t0_c"] = s / m;  // only the temperature's variation is told from a bias
    }
    p.params[it.key()] = u->second;
    auto c = diag::make_candidate(e.name);
    c->set(p);
    Contribution k;
    k.resize(r.n);
    c->contribute(r, k);
    // A recording that keeps a level of its own (levels.cpp) takes the effect's mean there.
    for (const auto& [from, to] : levelled_parts(r)) {
      for (int a = 0; a < 2; ++a) {
        double s = 0, m = 0;
        for (uint32_t i : r.heldout_rows) {
          if (i >= from && i < to) { s += k.v[a][i]; m += 1; }
        }
        if (m > 0) for (size_t i = from; i < to; ++i) k.v[a][i] -= static_cast<float>(s / m);
      }
    }
    double g = 0, peak = 0;
    for (uint32_t i : r.heldout_rows) {
      g += k.v[0][i] * k.v[0][i] + k.v[1][i] * k.v[1][i];
      peak = std::max<double>({peak, std::abs(k.v[0][i]), std::abs(k.v[1][i])});
    }
    // Where the effect acts (a tenth of its peak or more, each axis a row): the RMS there at the
    // limit, so that an effect confined to a few rows (a time shift in slews) is judged by what it
    // does where it shows, not diluted over the rest.
    double support = 0;
    for (uint32_t i : r.heldout_rows) {
      for (int a = 0; a < 2; ++a) support += std::abs(k.v[a][i]) >= 0.1 * peak && peak > 0;
    }
    g /= N * u->second * u->second;
    out[it.key()] = g > 0 ? std::sqrt(need / g) : std::numeric_limits<double>::infinity();
    acting = std::max(acting, support > 0 ? std::sqrt(need * N / support) : std::numeric_limits<double>::infinity());
  }
  if (acting_rms_arcsec && acting > 0) *acting_rms_arcsec = acting;
  return out;
}

// The verdict (docs/diagnosis.md): no_gap, explained, partly_explained or unexplained, and the
// remainder when something stays unexplained.
void decide_verdict(const Recording& r, Diagnosis& d, const ojson& flexible) {
  const double nf = d.noise_floor_arcsec;
  const double remainder = d.cause == "none" ? d.gap_before_arcsec : d.gap_after_all_arcsec;
  const bool held_gap = remainder > 1.5 * nf;
  const bool scatter = std::isfinite(d.excess_scatter()) && d.excess_scatter() > 2.0;
  const bool outl = d.outliers > 0;
  const bool found = d.cause != "none";
  if (!held_gap && !scatter && !outl) {
    d.verdict = found ? "explained" : "no_gap";
  } else {
    d.verdict = found ? "partly_explained" : "unexplained";
  }
  std::vector<std::string> why;
  if (held_gap) {
    why.push_back(fmt::format("{:.2f}x the noise floor stays on the held-out steps", remainder / nf));
  }
  if (scatter) {
    why.push_back(fmt::format("the scatter within steps is {:.1f}x what the model expects", d.excess_scatter()));
  }
  if (outl) {
    why.push_back(fmt::format("{} outlier frame{} ({:.2f} %)", d.outliers, d.outliers == 1 ? "" : "s",
                              100 * d.outlier_fraction));
  }
  std::string causes;
  for (size_t k = 0; k < d.causes.size(); ++k) causes += (k ? " and " : "") + d.causes[k].name;
  if (d.verdict == "no_gap") {
    d.verdict_sentence = fmt::format("No gap: the recording matches the model within its noise ({:.3f} arcsec held out "
                                     "against a noise floor of {:.3f}).",
                                     remainder, nf);
  } else if (d.verdict == "explained") {
    d.verdict_sentence = fmt::format("Explained: {} account{} for the gap ({:.3f} -> {:.3f} arcsec held out, noise "
                                     "floor {:.3f}).",
                                     causes, d.causes.size() > 1 ? "" : "s", d.gap_before_arcsec, remainder, nf);
  } else if (d.verdict == "partly_explained") {
    d.verdict_sentence = fmt::format("Partly explained: {} account{} for part of the gap ({:.3f} -> {:.3f} arcsec "
                                     "held out), but {}.",
                                     causes, d.causes.size() > 1 ? "" : "s", d.gap_before_arcsec, remainder,
                                     fmt::join(why, "; "));
  } else {
    d.verdict_sentence = fmt::format("Unexplained: no catalogued effect is material, yet {}.", fmt::join(why, "; "));
  }
  if (d.verdict != "partly_explained" && d.verdict != "unexplained") return;
  Diagnosis::Remainder rem;
  rem.heldout_rms_arcsec = remainder;
  rem.flexible_shrink = flexible;
  std::vector<WhereEntry> extra;
  if (scatter) {
    const double x = d.excess_scatter();
    extra.push_back({"within_step", "both", std::clamp(1.0 - 1.0 / (x * x), 0.0, 1.0),
                     fmt::format("one sample scatters {:.4f} arcsec about its step mean, {:.1f}x the expected {:.4f} "
                                 "(vibration, or noise the model does not know)",
                                 d.within_step_scatter_arcsec, x, d.expected_scatter_arcsec)});
  }
  if (outl) {
    extra.push_back({"outlier_frames", "both", d.outlier_fraction,
                     fmt::format("{} isolated frame{} more than 6 robust sigmas from their step, in {} step{} (kept out "
                                 "of every fit)",
                                 d.outliers, d.outliers == 1 ? "" : "s", d.outlier_steps.size(),
                                 d.outlier_steps.size() == 1 ? "" : "s")});
  }
  if (held_gap) {
    rem.where = d.where_after;
    rem.where.insert(rem.where.end(), extra.begin(), extra.end());
    // In order of share: when no factor stands out (where_after then lists the three that come
    // closest, with shares near 0), a vibration's excess scatter is what the remainder is.
    std::stable_sort(rem.where.begin(), rem.where.end(),
                     [](const WhereEntry& a, const WhereEntry& b) { return a.share > b.share; });
  } else {
    rem.where = extra;
  }
  d.unexplained = std::move(rem);
  (void)r;
}

}  // namespace fpss::diag
