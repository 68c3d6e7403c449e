// Where the residual lies: its share explained by each factor, and the flexible-model shrink.
#include <fmt/format.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include "calib/diagnosis/internal.h"

namespace fpss::diag {
namespace {

using ojson = nlohmann::ordered_json;


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

// Hat functions of a linear spline with k knots evenly over [-1, 1]: over a +-1500 arcsec field a
// knot every ~50 arcsec, so a cyclic error of a few hundred arcsec period (a gimbal encoder's) is
// resolved wherever slews pass.
constexpr int kAngleKnots = 64;
// A spline knot the fit rows barely reach (less than this much hat weight) says nothing: rows
// that lean on it are neither predicted nor judged. Dwells 200 arcsec apart sample a cyclic error
// of a few hundred arcsec below its Nyquist rate; interpolating between them would blame the
// factor for a pattern the fit rows never showed.
constexpr double kMinKnotSupport = 2.0;
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
ojson flexible_shrink(const Recording& r, const std::vector<float> e_in[2], const std::vector<Factor>& factors,
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
  std::vector<float> e[2] = {{e_in[0].begin(), e_in[0].end()}, {e_in[1].begin(), e_in[1].end()}};
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

struct Pick {
  double gain[2] = {0, 0};
  Eigen::VectorXd x[2];
  Eigen::VectorXd support[2];  // spline factors: each knot's hat weight on the fit rows
};

// Whether a spline factor's fit says anything at a row with basis phi: every knot it leans on
// is supported by the fit rows (other factors: always).
bool supported(const Eigen::VectorXd& phi, const Eigen::VectorXd& support) {
  if (support.size() == 0) return true;
  for (int k = 0; k < phi.size(); ++k) if (phi(k) != 0 && support(k) < kMinKnotSupport) return false;
  return true;
}

// The state the search for where the residual lies shares between its steps. Factors' basis
// functions refer to its members, so it stays where it was built.
class WhereSearch {
 public:
  WhereSearch(const Recording& r, const std::vector<float> e_in[2], double noise_arcsec)
      : r(r), e_in(e_in), F(r.fit_rows), H(r.heldout_rows), noise_arcsec(noise_arcsec) {
    for (uint32_t i : H) total += e_in[0][i] * e_in[0][i] + e_in[1][i] * e_in[1][i];
  }
  WhereSearch(const WhereSearch&) = delete;
  WhereSearch& operator=(const WhereSearch&) = delete;

  std::vector<WhereEntry> run(ojson* flexible) {
    if (total <= 0) return out;
    build_factors();
    // Greedy: the factor whose fit (on the fit rows) removes most of what is left on the held-out
    // rows, less 2 noise variances per parameter so that a flexible factor does not win by noise,
    // takes its share; its fit is removed and the next is sought. Shares therefore add up.
    e[0].assign(e_in[0].begin(), e_in[0].end());
    e[1].assign(e_in[1].begin(), e_in[1].end());
    penalty = 2.0 * noise_arcsec * noise_arcsec;
    used.assign(factors.size(), false);
    for (int round = 0; round < 5; ++round) {
      if (!greedy_round()) break;
    }
    std::stable_sort(out.begin(), out.end(), [](const WhereEntry& a, const WhereEntry& b) { return a.share > b.share; });
    release(e[0]);  // the flexible model works on its own copy
    release(e[1]);
    if (flexible) *flexible = flexible_shrink(r, e_in, factors, out);
    return out;
  }

 private:
  template <typename V>
  Scale range(V&& v) const {
    Scale s{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
    for (size_t i = 0; i < r.n; ++i) {
      if (r.use[i] == Use::excluded) continue;
      const double x = v(i);
      if (std::isfinite(x)) { s.lo = std::min(s.lo, x); s.hi = std::max(s.hi, x); }
    }
    if (!(s.hi >= s.lo)) s = Scale{};
    return s;
  }
  bool moving(size_t i, int a) const {
    return r.steps[r.step_of[i]].kind == StepKind::motion && std::abs(r.vel[a][i]) > 1.0;
  }
  void build_factors();
  double fit_factor(const Factor& f, int a, Eigen::VectorXd& x, Eigen::VectorXd& support) const;
  std::string describe(const Factor& f, int a) const;
  bool greedy_round();

  const Recording& r;
  const std::vector<float>* e_in;
  const std::vector<uint32_t>& F;
  const std::vector<uint32_t>& H;
  const double noise_arcsec;
  const char* axis_name[2] = {"pitch", "yaw"};
  double total = 0;
  std::vector<WhereEntry> out;
  Scale ang[2], rate[2], time, since, temp;
  std::vector<Factor> factors;
  std::vector<float> e[2];  // what is left, float: shares need no more (and a large recording's memory does)
  double penalty = 0;
  std::vector<bool> used;
};

void WhereSearch::build_factors() {
  ang[0] = range([&](size_t i) { return r.ref[0][i]; });
  ang[1] = range([&](size_t i) { return r.ref[1][i]; });
  rate[0] = range([&](size_t i) { return moving(i, 0) ? r.vel[0][i] : kNaN; });
  rate[1] = range([&](size_t i) { return moving(i, 1) ? r.vel[1][i] : kNaN; });
  time = range([&](size_t i) { return r.t[i]; });
  since = range([&](size_t i) { return r.since_move[i]; });
  temp = range([&](size_t i) { return r.temp[i]; });
  auto one = [](size_t, int) { return 1.0; };

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
}

double WhereSearch::fit_factor(const Factor& f, int a, Eigen::VectorXd& x, Eigen::VectorXd& support) const {
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(f.dims, f.dims);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(f.dims), phi(f.dims);
  support = f.spline ? Eigen::VectorXd::Zero(f.dims) : Eigen::VectorXd();
  // Only the basis functions that are nonzero at a row enter its products: a spline row has two
  // of its 64 (a dense rank-one update would spend 2,000 products where 3 count). The sums are
  // the dense update's, term by term (a zero product adds nothing), in the same row order.
  std::vector<int> nz(f.dims);
  for (uint32_t i : F) {
    f.basis(i, a, phi.data());
    int m = 0;
    for (int k = 0; k < f.dims; ++k) if (phi(k) != 0) nz[m++] = k;
    const double ei = e[a][i];
    for (int p = 0; p < m; ++p) {
      const int k = nz[p];
      for (int q = 0; q <= p; ++q) G(k, nz[q]) += phi(k) * phi(nz[q]);
      b(k) += phi(k) * ei;
      if (f.spline) support(k) += std::abs(phi(k));
    }
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
    const double pred = supported(phi, support) ? phi.dot(x) : 0.0;
    before += e[a][i] * e[a][i];
    after += (e[a][i] - pred) * (e[a][i] - pred);
  }
  return before - after;
}

std::string WhereSearch::describe(const Factor& f, int a) const {
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
}

// One round of the greedy search; false when no factor stands out any more.
bool WhereSearch::greedy_round() {
  int best = -1;
  double best_adj = 0.01 * total;  // a factor must take at least 1 % of the gap
  Pick best_pick;
  std::vector<std::pair<double, int>> raw;  // for the noise-only case: what comes closest
  for (size_t k = 0; k < factors.size(); ++k) {
    if (used[k]) continue;
    Pick p;
    for (int a = 0; a < 2; ++a) p.gain[a] = fit_factor(factors[k], a, p.x[a], p.support[a]);
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
    return false;
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
      if (supported(phi, best_pick.support[a])) e[a][i] -= phi.dot(best_pick.x[a]);
    }
  }
  return true;
}

}  // namespace

std::vector<WhereEntry> where_of(const Recording& r, const std::vector<float> e_in[2], double noise_arcsec,
                                 ojson* flexible) {
  WhereSearch search(r, e_in, noise_arcsec);
  return search.run(flexible);
}

ojson where_json(const std::vector<WhereEntry>& w) {
  ojson a = ojson::array();
  for (const auto& e : w) a.push_back({{"factor", e.factor}, {"axis", e.axis}, {"share", e.share}, {"detail", e.detail}});
  return a;
}

}  // namespace fpss::diag
