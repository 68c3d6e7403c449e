// The diagnosis: noise floor, observability, every candidate fitted on the fit steps and scored
// on the held-out steps, a second effect when the first leaves a gap, and where the gap lies.
#include "calib/diagnosis.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
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
  // order 2: second differences (var 6 sigma^2), order 1: first differences (var 2 sigma^2).
  auto estimate = [&](StepKind kind, int a, int order, size_t* used) {
    std::vector<double> d2;
    for (const auto& s : r.steps) {
      if (s.kind != kind) continue;
      for (size_t i = s.begin + 1; i + (order == 2 ? 1 : 0) < s.end; ++i) {
        if (r.outlier[i] || r.outlier[i - 1] || (order == 2 && r.outlier[i + 1])) continue;
        const double d = order == 2 ? r.res[a][i + 1] - 2 * r.res[a][i] + r.res[a][i - 1] : r.res[a][i] - r.res[a][i - 1];
        d2.push_back(d * d);
      }
    }
    *used = d2.size();
    if (d2.size() < 10) return kNaN;
    double ms = std::accumulate(d2.begin(), d2.end(), 0.0) / static_cast<double>(d2.size());
    for (int it = 0; it < 3; ++it) {
      const double lim = 16.0 * ms;
      double s = 0;
      size_t m = 0;
      for (double v : d2) if (v <= lim) { s += v; ++m; }
      if (m == 0) break;
      ms = s / static_cast<double>(m);
    }
    return std::sqrt(ms / (order == 2 ? 6.0 : 2.0));
  };
  double sig[2];
  for (int a = 0; a < 2; ++a) {
    size_t used = 0;
    sig[a] = estimate(StepKind::dwell, a, 2, &used);
    if (!std::isfinite(sig[a])) sig[a] = estimate(StepKind::motion, a, 2, &used);
    if (!std::isfinite(sig[a])) sig[a] = estimate(StepKind::dwell, a, 1, &used);
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

// One effect is a special case of the other: a refitted transfer function contains any bias
// (C1) and scale factor (C1, C2, C3, C6 scaled together). Such pairs are never fitted.
bool contained(const std::string& a, const std::string& b) {
  auto is = [&](const char* x, const char* y) { return (a == x && b == y) || (a == y && b == x); };
  return is("coefficients", "bias") || is("coefficients", "scale_factor");
}

// Why two effects can look alike, for the ambiguity note.
std::string why_alike(const std::string& a, const std::string& b) {
  auto is = [&](const char* x, const char* y) { return (a == x && b == y) || (a == y && b == x); };
  if (is("backlash", "settling")) {
    return "a settling with a time constant much longer than the dwells acts like backlash at rest; slews (moving, "
           "no settling) or longer dwells tell them apart";
  }
  if (is("drift", "temperature") || is("bias", "temperature")) {
    return "the temperature follows time (or barely changes) in this recording; a non-monotonic temperature profile "
           "tells them apart";
  }
  if (is("scale_factor", "coefficients") || is("bias", "coefficients")) {
    return "a refitted transfer function absorbs any offset or scale; more offsets or a wider field tell them apart";
  }
  if (is("boresight_roll", "axis_nonorthogonality")) {
    return "both turn pitch into yaw; only a roll also turns yaw into pitch, which needs yaw offsets";
  }
  if (a == "none" || b == "none") return "the effect is barely above the noise of this recording";
  return "the held-out data barely tells them apart";
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
  s.result.degenerate = s.cand->degenerate();
  return s;
}

// ------------------------------------------------------------------ where

// Each factor explains the residual through a few smooth functions of itself (a cubic in the
// factor, its own constant for rows where it does not apply), fitted on the fit rows and judged
// on the held-out rows, so a flexible factor cannot claim what it merely memorised.
struct Factor {
  std::string name;
  int dims = 0;
  // Basis functions of row i for axis a, written to phi[0..dims).
  std::function<void(size_t i, int a, double* phi)> basis;
  // For the words: the value binned, NaN for "does not apply", and the sign the residual is read with.
  std::function<double(size_t i, int a)> value;
  std::function<double(size_t i, int a)> sign;
  int bins = 10;
  bool discrete = false;
  std::string nan_label;
  bool spline = false;  // hat functions of a linear spline: fitted with a roughness penalty
};

std::string signed_num(double v, int prec = 2) { return fmt::format("{:+.{}f}", v, prec); }

int bin_of(double x, double lo, double hi, int bins) {
  if (!std::isfinite(x)) return bins;
  if (hi <= lo) return 0;
  return std::clamp(static_cast<int>((x - lo) / (hi - lo) * bins), 0, bins - 1);
}

// Scales x from [lo, hi] to [-1, 1].
struct Scale {
  double lo = -1, hi = 1;
  double operator()(double x) const { return hi > lo ? 2 * (x - lo) / (hi - lo) - 1 : 0.0; }
};

// Hat functions of a linear spline with k knots evenly over [-1, 1].
constexpr int kAngleKnots = 24;
void hat(double x, int k, double* phi) {
  std::fill(phi, phi + k, 0.0);
  const double u = std::clamp((x + 1) * 0.5 * (k - 1), 0.0, k - 1.0);
  const int j = std::min(static_cast<int>(u), k - 2);
  phi[j] = 1 - (u - j);
  phi[j + 1] = u - j;
}

void cubic(double x, double* phi) {
  phi[0] = 1;
  phi[1] = x;
  phi[2] = x * x;
  phi[3] = x * x * x;
}

// How far a flexible, non-physical model of the leading factor(s) shrinks the held-out
// remainder: per axis a linear spline (16 knots over the factor's range, its own constant where
// the factor does not apply) in each of the one or two leading factors, fitted additively on the
// fit rows, judged on the held-out rows. A large shrink says the remainder is a smooth function
// of that factor that no catalogued effect has; a small one that it is not (noise, outliers, or
// a factor the list lacks).
ojson flexible_shrink(const Recording& r, const std::vector<double> e_in[2], const std::vector<Factor>& factors,
                      const std::vector<WhereEntry>& lead) {
  std::vector<const Factor*> use;
  for (const auto& w : lead) {
    if (use.size() >= 2 || w.share < 0.05) break;
    for (const auto& f : factors) {
      if (f.name == w.factor && std::find(use.begin(), use.end(), &f) == use.end()) use.push_back(&f);
    }
  }
  double before = 0;
  for (uint32_t i : r.heldout_rows) before += e_in[0][i] * e_in[0][i] + e_in[1][i] * e_in[1][i];
  const double n_h = 2.0 * static_cast<double>(r.heldout_rows.size());
  ojson j{{"factors", ojson::array()}, {"model", "additive linear splines, 16 knots per factor and axis, fitted on the "
                                                 "fit rows"}};
  if (use.empty() || before <= 0) {
    j["heldout_rms_arcsec"] = std::sqrt(before / std::max(n_h, 1.0));
    j["ratio"] = 1.0;
    return j;
  }
  std::vector<double> e[2] = {e_in[0], e_in[1]};
  constexpr int kKnots = 16;
  for (const Factor* f : use) {
    j["factors"].push_back(f->name);
    for (int a = 0; a < 2; ++a) {
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (size_t i = 0; i < r.n; ++i) {
        const double v = f->value(i, a);
        if (r.use[i] != Use::excluded && std::isfinite(v)) { lo = std::min(lo, v); hi = std::max(hi, v); }
      }
      const int dims = kKnots + 1;
      auto basis = [&](size_t i, double* phi) {
        std::fill(phi, phi + dims, 0.0);
        const double v = f->value(i, a);
        if (!std::isfinite(v) || !(hi > lo)) { phi[kKnots] = std::isfinite(v) ? 0.0 : 1.0; if (std::isfinite(v)) phi[0] = 1; return; }
        const double x = std::clamp((v - lo) / (hi - lo) * (kKnots - 1), 0.0, kKnots - 1.0);
        const int k = std::min(static_cast<int>(x), kKnots - 2);
        const double w = x - k, sg = f->sign(i, a);
        phi[k] = (1 - w) * sg;
        phi[k + 1] = w * sg;
      };
      Eigen::MatrixXd G = Eigen::MatrixXd::Zero(dims, dims);
      Eigen::VectorXd b = Eigen::VectorXd::Zero(dims), phi(dims);
      for (uint32_t i : r.fit_rows) {
        basis(i, phi.data());
        G.selfadjointView<Eigen::Lower>().rankUpdate(phi);
        b += phi * e[a][i];
      }
      G = G.selfadjointView<Eigen::Lower>();
      const double lam = 1e-3 * (G.diagonal().mean() + 1e-30);  // roughness penalty, as in where_of
      for (int k = 0; k + 2 < kKnots; ++k) {
        const int idx[3] = {k, k + 1, k + 2};
        const double c[3] = {1, -2, 1};
        for (int u = 0; u < 3; ++u) for (int v = 0; v < 3; ++v) G(idx[u], idx[v]) += lam * c[u] * c[v];
      }
      G.diagonal().array() += 1e-6 * (G.diagonal().maxCoeff() + 1e-30);
      const Eigen::VectorXd x = G.ldlt().solve(b);
      for (size_t i = 0; i < r.n; ++i) {
        basis(i, phi.data());
        e[a][i] -= phi.dot(x);
      }
    }
  }
  double after = 0;
  for (uint32_t i : r.heldout_rows) after += e[0][i] * e[0][i] + e[1][i] * e[1][i];
  j["heldout_rms_arcsec"] = std::sqrt(after / n_h);
  j["ratio"] = std::sqrt(after / before);
  return j;
}

std::vector<WhereEntry> where_of(const Recording& r, const std::vector<double> e_in[2], double noise_arcsec,
                                 ojson* flexible = nullptr) {
  const std::vector<uint32_t>& F = r.fit_rows;
  const std::vector<uint32_t>& H = r.heldout_rows;
  double total = 0;
  for (uint32_t i : H) total += e_in[0][i] * e_in[0][i] + e_in[1][i] * e_in[1][i];
  std::vector<WhereEntry> out;
  if (total <= 0) return out;
  const char* axis_name[2] = {"pitch", "yaw"};

  auto range = [&](auto&& v) {
    Scale s{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
    for (size_t i = 0; i < r.n; ++i) {
      if (r.use[i] == Use::excluded) continue;
      const double x = v(i);
      if (std::isfinite(x)) { s.lo = std::min(s.lo, x); s.hi = std::max(s.hi, x); }
    }
    if (!(s.hi >= s.lo)) s = Scale{};
    return s;
  };
  const Scale ang[2] = {range([&](size_t i) { return r.ref[0][i]; }), range([&](size_t i) { return r.ref[1][i]; })};
  auto moving = [&](size_t i, int a) {
    return r.steps[r.step_of[i]].kind == StepKind::motion && std::abs(r.vel[a][i]) > 1.0;
  };
  const Scale rate[2] = {range([&](size_t i) { return moving(i, 0) ? r.vel[0][i] : kNaN; }),
                         range([&](size_t i) { return moving(i, 1) ? r.vel[1][i] : kNaN; })};
  const Scale time = range([&](size_t i) { return r.t[i]; });
  const Scale since = range([&](size_t i) { return r.since_move[i]; });
  const Scale temp = range([&](size_t i) { return r.temp[i]; });
  auto one = [](size_t, int) { return 1.0; };

  std::vector<Factor> factors;
  factors.push_back({"constant", 1, [](size_t, int, double* p) { p[0] = 1; }, [](size_t, int) { return 0.0; }, one, 1,
                     false, ""});
  // Angles: a linear spline (kAngleKnots knots over the range covered), so that a cyclic error
  // of a few hundred arcsec period is as visible as a smooth one.
  factors.push_back({"angle", kAngleKnots, [&](size_t i, int a, double* p) { hat(ang[a](r.ref[a][i]), kAngleKnots, p); },
                     [&](size_t i, int a) { return r.ref[a][i]; }, one, 12, false, "", true});
  factors.push_back({"cross_angle", kAngleKnots, [&](size_t i, int a, double* p) { hat(ang[1 - a](r.ref[1 - a][i]), kAngleKnots, p); },
                     [&](size_t i, int a) { return r.ref[1 - a][i]; }, one, 12, false, "", true});
  // Linear in the rate: slews come at few rates (a held-out segment may run at a rate and
  // direction the fit rows lack), and a straight line is what a few rates support.
  factors.push_back({"slew_rate", 3,
                     [&](size_t i, int a, double* p) {
                       const bool m = moving(i, a);
                       p[0] = m ? 0.0 : 1.0;
                       p[1] = m ? 1.0 : 0.0;
                       p[2] = m ? rate[a](r.vel[a][i]) : 0.0;
                     },
                     [&](size_t i, int a) { return moving(i, a) ? r.vel[a][i] : kNaN; }, one, 8, false, "at rest"});
  factors.push_back({"approach_direction", 3,
                     [&](size_t i, int a, double* p) {
                       p[0] = r.dir[a][i] < 0; p[1] = r.dir[a][i] == 0; p[2] = r.dir[a][i] > 0;
                     },
                     [&](size_t i, int a) { return static_cast<double>(r.dir[a][i]); }, one, 3, true, ""});
  factors.push_back({"time", 4, [&](size_t i, int, double* p) { cubic(time(r.t[i]), p); },
                     [&](size_t i, int) { return r.t[i]; }, one, 10, false, ""});
  // Settling acts in the direction of the move: the decay is read signed by it.
  factors.push_back({"time_since_move", 6,
                     [&](size_t i, int a, double* p) {
                       const double tm = r.since_move[i];
                       const bool ok = std::isfinite(tm);
                       p[0] = ok ? 0.0 : 1.0;
                       p[1] = ok ? 1.0 : 0.0;
                       cubic(ok ? since(tm) : 0.0, p + 2);
                       for (int k = 2; k < 6; ++k) p[k] *= ok ? r.move_dir[a][i] : 0.0;
                     },
                     [&](size_t i, int a) { return r.move_dir[a][i] != 0 ? r.since_move[i] : kNaN; },
                     [&](size_t i, int a) { return r.move_dir[a][i] != 0 ? static_cast<double>(r.move_dir[a][i]) : 1.0; },
                     8, false, "while moving or before any move"});
  if (r.has_temperature) {
    factors.push_back({"temperature", 5,
                       [&](size_t i, int, double* p) {
                         const bool ok = std::isfinite(r.temp[i]);
                         p[0] = ok ? 0.0 : 1.0;
                         cubic(ok ? temp(r.temp[i]) : 0.0, p + 1);
                         if (!ok) p[1] = 0;
                       },
                       [&](size_t i, int) { return r.temp[i]; }, one, 10, false, "without a temperature reading"});
  }


  // Greedy: the factor whose fit (on the fit rows) removes most of what is left on the held-out
  // rows, less 2 noise variances per parameter so that a flexible factor does not win by noise,
  // takes its share; its fit is removed and the next is sought. Shares therefore add up.
  std::vector<double> e[2] = {e_in[0], e_in[1]};
  const double penalty = 2.0 * noise_arcsec * noise_arcsec;
  std::vector<bool> used(factors.size(), false);
  struct Pick {
    double gain[2] = {0, 0};
    Eigen::VectorXd x[2];
  };
  auto fit_factor = [&](const Factor& f, int a, Eigen::VectorXd& x) {
    Eigen::MatrixXd G = Eigen::MatrixXd::Zero(f.dims, f.dims);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(f.dims), phi(f.dims);
    for (uint32_t i : F) {
      f.basis(i, a, phi.data());
      G.selfadjointView<Eigen::Lower>().rankUpdate(phi);
      b += phi * e[a][i];
    }
    G = G.selfadjointView<Eigen::Lower>();
    if (f.spline) {
      // A roughness penalty on the spline's second differences: knots the fit rows barely reach
      // follow their neighbours instead of swinging (the held-out rows may lie there).
      const double lam = 1e-3 * (G.diagonal().mean() + 1e-30);
      for (int k = 0; k + 2 < f.dims; ++k) {
        const int idx[3] = {k, k + 1, k + 2};
        const double c[3] = {1, -2, 1};
        for (int u = 0; u < 3; ++u) for (int v = 0; v < 3; ++v) G(idx[u], idx[v]) += lam * c[u] * c[v];
      }
    }
    G.diagonal().array() += 1e-9 * (G.diagonal().maxCoeff() + 1e-30);
    x = G.ldlt().solve(b);
    double before = 0, after = 0;
    for (uint32_t i : H) {
      f.basis(i, a, phi.data());
      const double pred = phi.dot(x);
      before += e[a][i] * e[a][i];
      after += (e[a][i] - pred) * (e[a][i] - pred);
    }
    return before - after;
  };
  auto describe = [&](const Factor& f, int a) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (size_t i = 0; i < r.n; ++i) {
      const double v = f.value(i, a);
      if (r.use[i] != Use::excluded && std::isfinite(v)) { lo = std::min(lo, v); hi = std::max(hi, v); }
    }
    if (f.discrete) { lo = -1.5; hi = 1.5; }
    const int nb = f.bins;
    std::vector<double> s2(nb + 1, 0.0), c2(nb + 1, 0.0);
    for (size_t i = 0; i < r.n; ++i) {
      if (r.use[i] == Use::excluded) continue;
      const int bn = bin_of(f.value(i, a), lo, hi, nb);
      s2[bn] += e[a][i] * f.sign(i, a);
      c2[bn] += 1;
    }
    if (f.name == "constant") return fmt::format("mean residual {} arcsec", signed_num(c2[0] > 0 ? s2[0] / c2[0] : 0.0));
    auto label = [&](int bn) -> std::string {
      if (bn == nb) return f.nan_label;
      if (f.discrete) {
        const int d = bn - 1;
        return d == 0 ? "before any move of this axis" : (d > 0 ? "after motion in +" : "after motion in -");
      }
      const double w = (hi - lo) / nb, x0 = lo + bn * w, x1 = lo + (bn + 1) * w;
      if (f.name == "angle" || f.name == "cross_angle") {
        return fmt::format("at {} {:.0f}..{:.0f} arcsec", axis_name[f.name == "angle" ? a : 1 - a], x0, x1);
      }
      if (f.name == "slew_rate") return fmt::format("at {} rates {:+.0f}..{:+.0f} arcsec/s", axis_name[a], x0, x1);
      if (f.name == "time") return fmt::format("at time {:.1f}..{:.1f} s", x0, x1);
      if (f.name == "time_since_move") return fmt::format("{:.2f}..{:.2f} s after a move", x0, x1);
      return fmt::format("at {:.2f}..{:.2f} C", x0, x1);
    };
    int bmax = -1, bmin = -1;
    for (int bn = 0; bn <= nb; ++bn) {
      if (c2[bn] < 3) continue;
      const double m = s2[bn] / c2[bn];
      if (bmax < 0 || m > s2[bmax] / c2[bmax]) bmax = bn;
      if (bmin < 0 || m < s2[bmin] / c2[bmin]) bmin = bn;
    }
    if (bmax < 0) return std::string();
    return fmt::format("{}mean residual {} arcsec {}, {} {}",
                       f.name == "time_since_move" ? "in the direction of the move, " : "",
                       signed_num(s2[bmax] / c2[bmax]), label(bmax), signed_num(s2[bmin] / c2[bmin]), label(bmin));
  };

  for (int round = 0; round < 5; ++round) {
    int best = -1;
    double best_adj = 0.01 * total;  // a factor must take at least 1 % of the gap
    Pick best_pick;
    std::vector<std::pair<double, int>> raw;  // for the noise-only case: what comes closest
    for (size_t k = 0; k < factors.size(); ++k) {
      if (used[k]) continue;
      Pick p;
      for (int a = 0; a < 2; ++a) p.gain[a] = fit_factor(factors[k], a, p.x[a]);
      const double adj = p.gain[0] + p.gain[1] - penalty * 2 * factors[k].dims;
      raw.push_back({p.gain[0] + p.gain[1], static_cast<int>(k)});
      if (adj > best_adj) { best_adj = adj; best = static_cast<int>(k); best_pick = p; }
    }
    if (best < 0) {
      if (out.empty()) {  // nothing stands out: the three that come closest, with their (small) shares
        std::sort(raw.begin(), raw.end(), std::greater<>());
        for (size_t q = 0; q < raw.size() && q < 3; ++q) {
          const Factor& f = factors[raw[q].second];
          out.push_back({f.name, "both", std::max(0.0, raw[q].first) / total, describe(f, 0) + "; " + describe(f, 1)});
        }
      }
      break;
    }
    used[best] = true;
    const Factor& f = factors[best];
    const double g0 = std::max(0.0, best_pick.gain[0]), g1 = std::max(0.0, best_pick.gain[1]);
    const double hi = std::max(g0, g1), lo = std::min(g0, g1);
    WhereEntry w;
    w.factor = f.name;
    if (lo >= 0.01 * total && lo >= 0.25 * hi) {
      w.axis = "both";
      w.share = (g0 + g1) / total;
      w.detail = fmt::format("pitch: {}; yaw: {}", describe(f, 0), describe(f, 1));
    } else {
      const int a = g0 >= g1 ? 0 : 1;
      w.axis = axis_name[a];
      w.share = (a == 0 ? g0 : g1) / total;
      w.detail = describe(f, a);
      // The other axis's (smaller) part of the same factor, when it counts, as its own entry.
      if (lo >= 0.01 * total) {
        out.push_back({f.name, axis_name[1 - a], lo / total, describe(f, 1 - a)});
      }
    }
    w.share = std::min(w.share, 1.0);
    out.push_back(w);
    // Remove what this factor explains (its fit on the fit rows, applied everywhere).
    Eigen::VectorXd phi(f.dims);
    for (int a = 0; a < 2; ++a) {
      if (best_pick.gain[a] <= 0) continue;
      for (size_t i = 0; i < r.n; ++i) {
        f.basis(i, a, phi.data());
        e[a][i] -= phi.dot(best_pick.x[a]);
      }
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const WhereEntry& a, const WhereEntry& b) { return a.share > b.share; });
  if (flexible) *flexible = flexible_shrink(r, e_in, factors, out);
  return out;
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
  if (!e.degenerate.empty()) {
    j["degenerate"] = true;
    j["degenerate_why"] = e.degenerate;
  }
  if (!e.detection_limit.empty()) j["detection_limit"] = e.detection_limit;
  return j;
}

// Two candidates fitted jointly: alternating least squares (each on the residual less the
// other) for their nonlinear parameters, then one least-squares solve over the linear columns of
// both (alternation alone converges slowly when the two are correlated), until the fit rows' sum
// of squares settles.
struct JointFit {
  EffectResult e[2];
  Contribution sum;
  double score = 0;
};

void joint_linear_step(const Recording& r, Candidate* c[2], Contribution* k[2]) {
  std::vector<Contribution> cols[2];
  bool has[2];
  for (int q = 0; q < 2; ++q) has[q] = c[q]->columns(r, cols[q]);
  if (!has[0] && !has[1]) return;
  std::vector<const Contribution*> all_cols;
  for (int q = 0; q < 2; ++q) if (has[q]) for (const auto& col : cols[q]) all_cols.push_back(&col);
  const int m = static_cast<int>(all_cols.size());
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(m, m);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(m);
  for (uint32_t i : r.fit_rows) {
    for (int a = 0; a < 2; ++a) {
      double target = r.res[a][i];
      for (int q = 0; q < 2; ++q) if (!has[q]) target -= k[q]->v[a][i];
      for (int x = 0; x < m; ++x) {
        const double vx = all_cols[x]->v[a][i];
        if (vx == 0) continue;
        b(x) += vx * target;
        for (int y = 0; y <= x; ++y) G(x, y) += vx * all_cols[y]->v[a][i];
      }
    }
  }
  G = G.selfadjointView<Eigen::Lower>();
  G.diagonal().array() += 1e-12 * (G.diagonal().maxCoeff() + 1e-30);
  const Eigen::VectorXd w = G.ldlt().solve(b);
  int at = 0;
  for (int q = 0; q < 2; ++q) {
    if (!has[q]) continue;
    std::vector<double> wq(w.data() + at, w.data() + at + cols[q].size());
    at += static_cast<int>(cols[q].size());
    c[q]->set_linear(wq);
    c[q]->contribute(r, *k[q]);
  }
}

JointFit joint_fit(const Recording& r, const Scored& first, const std::string& name2, double ms0, double N) {
  auto c1 = first.cand->clone();
  auto c2 = diag::make_candidate(name2);
  Contribution k1 = first.contrib, k2, t, sum;
  k2.resize(r.n);
  t.resize(r.n);
  sum.resize(r.n);
  Candidate* c[2] = {c1.get(), c2.get()};
  Contribution* k[2] = {&k1, &k2};
  // A temperature's zero point and a constant offset (a bias, or the C1 of a refitted transfer
  // function) trade against each other: by the emulator's convention the profile starts at t0_c,
  // so t0_c is held at the first temperature reading.
  const bool offset = first.result.name == "bias" || name2 == "bias" || first.result.name == "coefficients" ||
                      name2 == "coefficients";
  if (offset && r.has_temperature) {
    double t_first = 0;
    for (size_t i = 0; i < r.n; ++i) if (std::isfinite(r.temp[i])) { t_first = r.temp[i]; break; }
    for (Candidate* q : c) if (q->name() == "temperature") q->hold("t0_c", t_first);
  }
  double prev = std::numeric_limits<double>::infinity();
  for (int it = 0; it < 20; ++it) {
    for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) t.v[a][i] = r.res[a][i] - k1.v[a][i];
    c2->fit(r, t, r.fit_rows);
    c2->contribute(r, k2);
    // The first's single fit had to absorb the second too; once the second is in, it starts
    // afresh (a refitted transfer function may otherwise stay in a wrong basin).
    if (it == 0) c1->restart();
    for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) t.v[a][i] = r.res[a][i] - k2.v[a][i];
    c1->fit(r, t, r.fit_rows);
    c1->contribute(r, k1);
    joint_linear_step(r, c, k);
    for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) sum.v[a][i] = k1.v[a][i] + k2.v[a][i];
    const double sse = mean_square(r, &sum, r.fit_rows);
    if (prev - sse <= 1e-7 * sse) break;
    prev = sse;
  }
  JointFit j;
  const double ms = mean_square(r, &sum, r.heldout_rows);
  j.score = penalised(ms, ms0, c1->parameters() + c2->parameters(), N);
  for (int q = 0; q < 2; ++q) {
    j.e[q].name = c[q]->name();
    j.e[q].params = c[q]->params();
    j.e[q].parameters = c[q]->parameters();
    j.e[q].notes = c[q]->notes();
    j.e[q].degenerate = c[q]->degenerate();
    j.e[q].fit_rms_arcsec = std::sqrt(mean_square(r, &sum, r.fit_rows));  // jointly
    j.e[q].heldout_rms_arcsec = std::sqrt(ms);
    j.e[q].score = j.score;
  }
  j.sum = std::move(sum);
  return j;
}

// Pooled within-step scatter of one sample about its step mean (dwells with three or more
// frames, outliers left out), RMS over both axes; NaN when no dwell has three frames.
double within_step_scatter(const Recording& r, const std::vector<double> e[2]) {
  double ss[2] = {0, 0};
  double dof = 0;
  for (const auto& s : r.steps) {
    if (s.kind != StepKind::dwell) continue;
    double sum[2] = {0, 0}, sq[2] = {0, 0}, m = 0;
    for (size_t i = s.begin; i < s.end; ++i) {
      if (r.outlier[i]) continue;
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
  ojson out = ojson::object();
  if (e.name == "none" || e.name == "coefficients" || !std::isfinite(noise) || noise <= 0) return out;
  static const std::map<std::string, double> unit = {
      {"pitch_arcsec", 0.01},         {"yaw_arcsec", 0.01},         {"pitch_arcsec_per_s", 1e-5},
      {"yaw_arcsec_per_s", 1e-5},     {"pitch_ppm", 1.0},           {"yaw_ppm", 1.0},
      {"roll_arcsec", 0.1},           {"skew_arcsec", 0.1},         {"width_arcsec", 0.01},
      {"amplitude_arcsec", 0.01},     {"skew_s", 1e-5},             {"pitch_arcsec_per_c", 0.001},
      {"yaw_arcsec_per_c", 0.001}};
  const double need = noise * noise * std::max(0.1, std::expm1(e.parameters * std::log(N) / N));
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
    double g = 0;
    for (uint32_t i : r.heldout_rows) g += k.v[0][i] * k.v[0][i] + k.v[1][i] * k.v[1][i];
    g /= N * u->second * u->second;
    out[it.key()] = g > 0 ? std::sqrt(need / g) : std::numeric_limits<double>::infinity();
  }
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
  } else {
    rem.where = extra;
  }
  d.unexplained = std::move(rem);
  (void)r;
}

}  // namespace

bool Diagnosis::incomplete_recording() const {
  return std::any_of(not_observable.begin(), not_observable.end(), [](const NotObservable& n) { return n.incomplete_recording; });
}

ojson Diagnosis::to_json() const {
  ojson j;
  j["source"] = source;
  j["verdict"] = verdict;
  j["verdict_sentence"] = verdict_sentence;
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
      {"cause", "the best score that also takes at least 0.1 x noise floor^2 off the held-out mean square; none "
                "when no candidate does"},
      {"second_effect", "when the cause leaves more than 1.2x the noise floor: around each of the three best single "
                        "effects by held-out score and the two best by fit-row residual, the others are screened on "
                        "what it leaves and the best three fitted jointly with it (alternating least squares); the best "
                        "pair is kept when its score beats the best single and it takes at least 0.1 x noise floor^2 "
                        "more off the held-out mean square; a refitted transfer function is never paired with a bias "
                        "or a scale factor (it contains both); causes[0] is the member that alone explains more, "
                        "causes[1] carries the joint figures"}};
  ojson no = ojson::array();
  for (const auto& n : not_observable) {
    no.push_back({{"name", n.name}, {"reason", n.reason}, {"incomplete_recording", n.incomplete_recording}});
  }
  j["not_observable"] = no;
  ojson amb = ojson::array();
  for (const auto& m : ambiguous_with) {
    amb.push_back({{"name", m.name}, {"score_difference", m.score_difference}, {"why", m.why}});
  }
  j["ambiguous_with"] = amb;
  if (unexplained) {
    j["unexplained"] = {{"heldout_rms_arcsec", unexplained->heldout_rms_arcsec},
                        {"where", where_json(unexplained->where)},
                        {"flexible_shrink", unexplained->flexible_shrink}};
  }
  j["within_step_scatter_arcsec"] = std::isfinite(within_step_scatter_arcsec) ? ojson(within_step_scatter_arcsec) : ojson();
  if (std::isfinite(expected_scatter_arcsec)) {
    j["expected_scatter_arcsec"] = expected_scatter_arcsec;
    j["excess_scatter"] = std::isfinite(excess_scatter()) ? ojson(excess_scatter()) : ojson();
  }
  j["outliers"] = {{"count", outliers}, {"fraction", outlier_fraction}, {"step_ids", outlier_steps},
                   {"rule", "more than 6 robust sigmas from the median of the frame and up to 3 neighbours on each side in its step, either axis "
                            "(calib/outliers.h); kept out of every fit and score"}};
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

  // No noise floor from the data (dwells of one or two samples, no slews): the best held-out
  // RMS bounds it from above.
  if (!std::isfinite(d.noise_floor_arcsec)) {
    d.noise_floor_arcsec = all.front().result.heldout_rms_arcsec;
    d.warnings.push_back("dwells too short for within-dwell scatter: the noise floor is the best candidate's held-out "
                         "RMS (an upper bound)");
  }
  // The cause: the best-scoring candidate that is also material, i.e. takes at least a tenth of
  // the noise variance off the held-out mean square (with very many rows, a statistically
  // significant but negligible effect would otherwise count); none if no candidate is.
  const double material = 0.1 * d.noise_floor_arcsec * d.noise_floor_arcsec;
  size_t pick = 0;
  for (size_t k = 0; k < all.size(); ++k) {
    const auto& e = all[k].result;
    if (e.name == "none") { pick = k; break; }
    if (!e.degenerate.empty()) continue;  // an ill-conditioned fit is never the cause
    if (ms0 - e.heldout_rms_arcsec * e.heldout_rms_arcsec >= material) { pick = k; break; }
  }
  const Scored& best = all[pick];
  d.cause = best.result.name;
  d.gap_after_arcsec = best.result.heldout_rms_arcsec;
  d.gap_after_all_arcsec = d.gap_after_arcsec;
  Contribution combined;
  combined.resize(r.n);
  if (d.cause != "none") {
    d.causes = {best.result};
    combined = best.contrib;
    // A second effect when the first leaves a gap above noise. Pairs are sought around a few
    // single effects (the best single may be a flexible stand-in for two simpler ones, e.g. a
    // settling with an endless tau for backlash plus drift): the others are screened on what
    // that one leaves, the three most promising are fitted jointly with it, and the best pair is
    // kept when it beats the best single's score.
    // Also when the cause is the catch-all refitted transfer function: it contains a bias and a
    // scale factor, and two simple effects may explain the same with far fewer parameters.
    if (opts.second_effect &&
        (d.gap_after_arcsec > opts.second_effect_gap_ratio * d.noise_floor_arcsec || d.cause == "coefficients")) {
      // Firsts: the three best held-out scores and the two best in-sample fits (with two effects
      // at once a single fit can be biased by the other effect so that it fails on the held-out
      // rows while still taking the most off the fit rows).
      std::vector<const Scored*> firsts;
      auto add_first = [&](const Scored* f) {
        if (f->result.name != "none" && std::find(firsts.begin(), firsts.end(), f) == firsts.end()) firsts.push_back(f);
      };
      for (size_t k = 0, m = 0; k < all.size() && m < 3; ++k) {
        if (all[k].result.name == "none" || !all[k].result.degenerate.empty()) continue;
        add_first(&all[k]);
        ++m;
      }
      std::vector<const Scored*> by_fit;
      for (const auto& s1 : all) if (s1.result.name != "none" && s1.result.degenerate.empty()) by_fit.push_back(&s1);
      std::sort(by_fit.begin(), by_fit.end(), [&](const Scored* a, const Scored* b) {
        return penalised(a->result.fit_rms_arcsec * a->result.fit_rms_arcsec, 1.0, a->result.parameters, N) <
               penalised(b->result.fit_rms_arcsec * b->result.fit_rms_arcsec, 1.0, b->result.parameters, N);
      });
      for (size_t k = 0; k < by_fit.size() && k < 2; ++k) add_first(by_fit[k]);
      std::optional<JointFit> pair;
      for (const Scored* fp : firsts) {
        const Scored& f = *fp;
        Contribution left, k2;
        left.resize(r.n);
        k2.resize(r.n);
        for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) left.v[a][i] = r.res[a][i] - f.contrib.v[a][i];
        std::vector<std::pair<double, std::string>> screened;
        for (const auto& s2 : all) {
          const std::string& name2 = s2.result.name;
          if (name2 == "none" || name2 == f.result.name || contained(f.result.name, name2)) continue;
          // One pass: the other fitted on what the first leaves, then both linear parts solved
          // together (a single's fit can be a compromise only a joint solve undoes).
          auto c1 = f.cand->clone();
          auto c2 = diag::make_candidate(name2);
          c2->fit(r, left, r.fit_rows);
          c2->contribute(r, k2);
          Contribution k1 = f.contrib;
          Candidate* cc[2] = {c1.get(), c2.get()};
          Contribution* kk[2] = {&k1, &k2};
          joint_linear_step(r, cc, kk);
          double ms = 0;
          for (uint32_t i : r.heldout_rows) {
            for (int a = 0; a < 2; ++a) {
              const double e = r.res[a][i] - k1.v[a][i] - k2.v[a][i];
              ms += e * e;
            }
          }
          screened.push_back({penalised(ms / N, ms0, c1->parameters() + c2->parameters(), N), name2});
        }
        std::sort(screened.begin(), screened.end());
        if (screened.size() > 3) screened.resize(3);
        for (const auto& sc : screened) {
          JointFit j = joint_fit(r, f, sc.second, ms0, N);
          if (!j.e[0].degenerate.empty() || !j.e[1].degenerate.empty()) continue;
          if (!pair || j.score < pair->score) pair = std::move(j);
        }
      }
      // Kept when it scores better than the best single and its second member is material: it
      // takes at least 0.1 x noise floor^2 off the held-out mean square its first leaves alone.
      auto single = [&](const std::string& n) -> const Scored& {
        for (const auto& s : all) if (s.result.name == n) return s;
        return all.front();
      };
      bool keep = pair && pair->score < best.result.score;
      EffectResult e1, e2;
      if (keep) {
        // In order: the one that alone explains more first.
        e1 = pair->e[0];
        e2 = pair->e[1];
        if (single(e2.name).result.score < single(e1.name).result.score) std::swap(e1, e2);
        const double alone = single(e1.name).result.heldout_rms_arcsec;
        keep = alone * alone - pair->e[1].heldout_rms_arcsec * pair->e[1].heldout_rms_arcsec >= material;
      }
      if (keep) {
        const Scored& lead = single(e1.name);
        e1.fit_rms_arcsec = lead.result.fit_rms_arcsec;  // the first's own figures, alone
        e1.heldout_rms_arcsec = lead.result.heldout_rms_arcsec;
        e1.score = lead.result.score;
        d.cause = e1.name;
        d.gap_after_arcsec = lead.result.heldout_rms_arcsec;
        d.causes = {e1, e2};
        d.gap_after_all_arcsec = e2.heldout_rms_arcsec;
        combined = pair->sum;
      }
    }
  }
  // Close competitors of the cause: singles within kAmbiguous score units (a likelihood ratio of
  // e^5) of its own score.
  constexpr double kAmbiguous = 10.0;
  if (d.cause != "none") {
    double cause_score = 0;
    for (const auto& s : all) if (s.result.name == d.cause) cause_score = s.result.score;
    for (const auto& s : all) {
      const std::string& n = s.result.name;
      if (std::any_of(d.causes.begin(), d.causes.end(), [&](const EffectResult& c) { return c.name == n; })) continue;
      const double diff = s.result.score - cause_score;
      if (std::abs(diff) < kAmbiguous) d.ambiguous_with.push_back({n, diff, why_alike(d.cause, n)});
    }
  }

  std::vector<double> before[2], after[2];
  for (int a = 0; a < 2; ++a) {
    before[a] = r.res[a];
    after[a].resize(r.n);
    for (size_t i = 0; i < r.n; ++i) after[a][i] = r.res[a][i] - combined.v[a][i];
  }
  d.where = where_of(r, before, d.noise_floor_arcsec);
  ojson flexible;
  d.where_after = where_of(r, after, d.noise_floor_arcsec, &flexible);

  // Noise is not structure: the within-step scatter of what the causes leave, against what the
  // sim expects of one sample about its step mean.
  d.within_step_scatter_arcsec = within_step_scatter(r, after);
  d.expected_scatter_arcsec = r.expected_scatter;
  d.outliers = static_cast<int64_t>(r.outliers);
  d.outlier_fraction = static_cast<double>(r.outliers) / static_cast<double>(r.n);
  d.outlier_steps = r.outlier_steps;
  for (auto& e : d.effects) e.detection_limit = detection_limit(r, e, d.noise_floor_arcsec, N);
  decide_verdict(r, d, flexible);

  // What the data holds and how it was divided.
  std::vector<int64_t> held_ids;
  size_t held_d = 0, held_m = 0;
  for (const auto& s : r.steps) {
    if (!s.heldout) continue;
    held_ids.push_back(s.id);
    (s.kind == StepKind::dwell ? held_d : held_m)++;
  }
  d.split = {
      {"method", fmt::format("by whole steps: of the dwells and of the slew segments, each in recording order, the "
                             "last of every {} steps is held out (a kind with two steps gives one to each side); rows "
                             "of one step are never divided",
                             opts.heldout_every)},
      {"fit_rows", r.fit_rows.size()},
      {"heldout_rows", r.heldout_rows.size()},
      {"excluded_rows", r.excluded_rows},
      {"excluded_why", fmt::format("the first and last {} s of every slew segment (the reference outside a segment "
                                   "is not recorded, so a time shift cannot be predicted there), the rows within the same margin of every reversal inside a step (a time shift moves where the sensor sees the turn), and outlier frames",
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
  if (d.cause != "none" && d.gap_after_all_arcsec > 1.5 * d.noise_floor_arcsec) {
    d.warnings.push_back(fmt::format(
        "the cause{} leave{} {:.2f}x the noise floor on the held-out rows: something else is at work too (see "
        "where_after)",
        d.causes.size() > 1 ? "s" : "", d.causes.size() > 1 ? "" : "s", d.gap_after_all_arcsec / d.noise_floor_arcsec));
  }
  for (const auto& m : d.ambiguous_with) {
    d.warnings.push_back(fmt::format("{} scores within {:.1f} of {}: {}", m.name, m.score_difference, d.cause, m.why));
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
