// The GLS of the changes (refine_gls): Ceres over runs of dwells, and its covariance.
#include <ceres/ceres.h>

#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>

#include "calib/refine.h"
#include "calib/units.h"

namespace fpss::fit {
namespace {

using Vec7 = Eigen::Matrix<double, 7, 1>;
using Mat7 = Eigen::Matrix<double, 7, 7>;

// f0 (the angle with C1 = 0, arcsec) and its gradient over u[1..7] at one count.
double angle_and_gradient(const Scaled& u, double n, Vec7& grad) {
  using J = ceres::Jet<double, 7>;
  J u27[7];
  for (int i = 0; i < 7; ++i) u27[i] = J(u[1 + i], i);
  const DwellLevelResidual f{n, 0.0, 1.0};
  const J a = f(u27, J(0.0));
  for (int i = 0; i < 7; ++i) grad(i) = a.v[i];
  return a.a;
}

// The coefficients as the fit moves them: polar (u[1..7], the reported form C3 sin(C4 N + C5)), or
// while iterating the Cartesian form a sin(w x) + b cos(w x) (x = N / kCountScale), where the
// amplitudes enter linearly: a slow sinusoid over less than half its period is nearly a polynomial,
// and in (amplitude, phase) its valley is long and curved (the solver then crawls along it for
// hundreds of iterations); in (a, b) only the frequencies are nonlinear.
//   v = (slope, a1, b1, a2, b2, w1, w2): slope u[1], a = C3' cos C5, b = C3' sin C5 in arcsec, w in
//   rad per kCountScale counts.
using Vec7Array = std::array<double, 7>;

Vec7Array cartesian_of(const Scaled& u) {
  return {u[1], u[2] * std::cos(u[4]), u[2] * std::sin(u[4]), u[5] * std::cos(u[7]), u[5] * std::sin(u[7]), u[3], u[6]};
}

// u[1..7] of the Cartesian v: a sin(w x) + b cos(w x) = hypot(a, b) sin(w x + atan2(b, a)). For
// doubles and jets alike, so the one transfer function is evaluated in either form.
template <typename T>
std::array<T, 7> polar_of(const T* v) {
  using std::atan2;
  using std::hypot;
  return {v[0], hypot(v[1], v[2]), v[5], atan2(v[2], v[1]), hypot(v[3], v[4]), v[6], atan2(v[4], v[3])};
}

Scaled polar_scaled(const Vec7Array& v) {
  const std::array<double, 7> p = polar_of(v.data());
  Scaled u{};
  std::copy(p.begin(), p.end(), u.begin() + 1);
  return u;
}

// The dwells' weights, 1 / variance in arcsec^-2, from the start's slope, computed when read (no
// array per dwell); float, as they were kept.
struct Weights {
  const GlsData* g;
  AxisCoeffs c0;
  float operator()(size_t k) const {
    if (!g->noise_known) return 1.0f;
    const auto v = parts(k);
    return static_cast<float>(1.0 / std::max(1e-30, v[0] + v[1] + v[2]));
  }
  // The dwell's variance by source (NoiseSource order), arcsec^2.
  std::array<double, 3> parts(size_t k) const {
    const double slope = rad_to_arcsec(transfer_slope(c0.data(), g->counts[k]));
    const double counts2 = g->var_counts2[k];
    const double sensor2 = g->var_sensor_counts2.empty() ? counts2 : std::min<double>(counts2, g->var_sensor_counts2[k]);
    return {slope * slope * sensor2, slope * slope * (counts2 - sensor2), g->var_ref_arcsec2(k)};
  }
};

// Per level: weighted sums of the dwells' e = ref - f0 and of the gradients.
struct LevelSums {
  double w = 0, we = 0, wee = 0;
  Vec7 wg = Vec7::Zero();
};

struct Pass {
  std::vector<LevelSums> lv;
  double cost = 0;  // sum w (e - level)^2
};

Pass level_pass(const GlsData& g, const Weights& w, const Scaled& u) {
  Pass p;
  p.lv.assign(g.levels, LevelSums{});
  Vec7 gr;
  for (size_t k = 0; k < g.size(); ++k) {
    const double e = g.ref_arcsec(k) - angle_and_gradient(u, g.counts[k], gr);
    LevelSums& l = p.lv[g.level_of(k)];
    const float wk = w(k);
    l.w += wk;
    l.we += wk * e;
    l.wee += wk * e * e;
    l.wg += wk * gr;
  }
  for (const auto& l : p.lv) {
    if (l.w > 0) p.cost += l.wee - l.we * l.we / l.w;
  }
  p.cost = std::max(0.0, p.cost);
  return p;
}

// R (8 x 8) of the QR of [J~ | r], the projected Jacobian and residuals, accumulated in chunks.
Eigen::Matrix<double, 8, 8> projected_r(const GlsData& g, const Weights& w, const Scaled& u,
                                        const Pass& p) {
  constexpr int kChunk = 256;
  Eigen::Matrix<double, Eigen::Dynamic, 8> stack(kChunk + 8, 8);
  Eigen::Matrix<double, 8, 8> r = Eigen::Matrix<double, 8, 8>::Zero();
  int rows = 0;
  bool have_r = false;
  auto reduce = [&] {
    if (have_r) stack.middleRows(rows, 8) = r;
    const int m = rows + (have_r ? 8 : 0);
    Eigen::HouseholderQR<Eigen::Matrix<double, Eigen::Dynamic, 8>> qr(stack.topRows(m));
    r.setZero();
    const int k = std::min(m, 8);
    r.topRows(k) = qr.matrixQR().topRows(k).triangularView<Eigen::Upper>();
    have_r = true;
    rows = 0;
  };
  Vec7 gr;
  for (size_t k = 0; k < g.size(); ++k) {
    const LevelSums& l = p.lv[g.level_of(k)];
    const double e = g.ref_arcsec(k) - angle_and_gradient(u, g.counts[k], gr);
    const double sw = std::sqrt(w(k));
    stack.row(rows).head<7>() = (sw * (gr - l.wg / l.w)).transpose();
    const double res = -sw * (e - l.we / l.w);
    stack(rows, 7) = res;
    if (++rows == kChunk) reduce();
  }
  if (rows > 0 || !have_r) reduce();
  return r;
}

// Pseudo-inverse of R11^T R11 (the covariance of u[1..7] up to scale).
struct Solve {
  Mat7 cov = Mat7::Zero();
  bool deficient = false;
};
Solve solve_r(const Eigen::Matrix<double, 8, 8>& r) {
  Solve s;
  const Mat7 r11 = r.topLeftCorner<7, 7>();
  Eigen::JacobiSVD<Mat7> svd(r11, Eigen::ComputeFullV);
  const auto& sv = svd.singularValues();
  const double tol = 1e-10 * sv(0);
  Vec7 inv = Vec7::Zero();
  for (int i = 0; i < 7; ++i) {
    if (sv(i) > tol) inv(i) = 1.0 / sv(i);
    else s.deficient = true;
  }
  const Mat7 v = svd.matrixV();
  s.cov = v * inv.cwiseAbs2().asDiagonal() * v.transpose();
  return s;
}

// A run of dwells of one reference level as one Ceres residual block, compressed by QR (TSQR):
// with [J | r] = Q R for the run's standardised residuals r and their Jacobian J over (v, level),
// the block returns R's last column (z, rho) with Jacobian R's first columns (R11, then a zero
// row), which give Ceres the same cost, J^T J and J^T r, so the same steps, while the problem
// holds 9 residuals per run of up to kDwellsPerBlock dwells instead of one per dwell: memory does
// not grow with the dwells. Parameter blocks: v (7, Cartesian, above) and the level (1, arcsec).
class DwellRun final : public ceres::CostFunction {
 public:
  static constexpr int kResiduals = 9;
  DwellRun(const GlsData& g, const Weights& w, size_t begin, size_t end) : g_(g), w_(w), begin_(begin), end_(end) {
    set_num_residuals(kResiduals);
    mutable_parameter_block_sizes()->push_back(7);
    mutable_parameter_block_sizes()->push_back(1);
  }

  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    using J = ceres::Jet<double, 8>;
    J v[7];
    for (int i = 0; i < 7; ++i) v[i] = J(p[0][i], i);
    const std::array<J, 7> u27 = polar_of(v);
    const J level(p[1][0], 7);
    const int m = static_cast<int>(end_ - begin_);
    Eigen::Matrix<double, Eigen::Dynamic, kResiduals> a(std::max(m, kResiduals), kResiduals);
    a.setZero();
    for (int i = 0; i < m; ++i) {
      const size_t k = begin_ + static_cast<size_t>(i);
      const double sw = std::sqrt(static_cast<double>(w_(k)));
      const J r = DwellLevelResidual{g_.counts[k], g_.ref_arcsec(k), sw}(u27.data(), level);
      if (!ceres::isfinite(r)) return false;
      a.row(i).head<8>() = r.v.transpose();
      a(i, 8) = r.a;
    }
    const Eigen::HouseholderQR<Eigen::Matrix<double, Eigen::Dynamic, kResiduals>> qr(a);
    const Eigen::Matrix<double, kResiduals, kResiduals> rr =
        qr.matrixQR().topRows<kResiduals>().triangularView<Eigen::Upper>();
    for (int i = 0; i < kResiduals; ++i) residuals[i] = rr(i, 8);
    if (jacobians) {
      if (jacobians[0]) {
        for (int i = 0; i < kResiduals; ++i) {
          for (int j = 0; j < 7; ++j) jacobians[0][i * 7 + j] = rr(i, j);
        }
      }
      if (jacobians[1]) {
        for (int i = 0; i < kResiduals; ++i) jacobians[1][i] = rr(i, 7);
      }
    }
    return true;
  }

 private:
  const GlsData& g_;
  const Weights& w_;
  size_t begin_, end_;
};

// Ceres's Levenberg-Marquardt over v (Cartesian) and the levels, from `u` (the start, whose levels
// `p` holds). Stops when a step gains less than max(1e-10, 1e-4 / dof) of the cost (a change of
// the transfer function of about a hundredth of its sigma), or after kMaxIterations.
Scaled minimise(const GlsData& g, const Weights& w, const Scaled& u, const Pass& p, GlsFit& out) {
  constexpr int kMaxIterations = 300;
  constexpr size_t kDwellsPerBlock = 256;
  Vec7Array v = cartesian_of(u);
  std::vector<double> levels(g.levels, 0.0);
  for (size_t l = 0; l < g.levels; ++l) levels[l] = p.lv[l].w > 0 ? p.lv[l].we / p.lv[l].w : 0.0;
  ceres::Problem problem;
  problem.AddParameterBlock(v.data(), 7);
  for (double& l : levels) problem.AddParameterBlock(&l, 1);
  for (size_t b = 0; b < g.size();) {
    const uint32_t level = g.level_of(b);
    size_t e = b + 1;
    while (e < g.size() && e - b < kDwellsPerBlock && g.level_of(e) == level) ++e;
    problem.AddResidualBlock(new DwellRun(g, w, b, e), nullptr, v.data(), &levels[level]);
    b = e;
  }
  const double dof = static_cast<double>(std::max<size_t>(1, g.size() > 7 + g.levels ? g.size() - 7 - g.levels : 1));
  ceres::Solver::Options so;
  // The levels are eliminated first (each run sees one): the Schur complement is 7 x 7.
  so.linear_solver_type = ceres::DENSE_SCHUR;
  so.max_num_iterations = kMaxIterations;
  so.function_tolerance = std::max(1e-10, 1e-4 / dof);
  so.gradient_tolerance = 1e-14;
  so.parameter_tolerance = 1e-12;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  out.iterations = static_cast<int>(summary.iterations.size()) - 1;
  out.converged = summary.termination_type == ceres::CONVERGENCE;
  return summary.IsSolutionUsable() ? polar_scaled(v) : u;
}

// To first order the fit is linear in the dwells' errors eps_k: du = cov sum_k w_k gt_k eps_k (gt_k
// the gradient less its level's weighted mean) and dC1 = sum_k a_l w_k / W_l eps_k - gbar . du. A_k
// is that 8-vector of weights of dwell k (C1 first); gt_k is returned beside it.
struct Linear {
  const GlsData& g;
  const Weights& w;
  const Scaled& u;
  const Pass& p;
  const Mat7& cov;
  const Vec7& gbar;
  // False for a dwell whose level has no weight.
  bool weights(size_t k, Eigen::Matrix<double, 8, 1>& a, Vec7& gt) const {
    const uint32_t l = g.level_of(k);
    const LevelSums& ls = p.lv[l];
    if (!(ls.w > 0)) return false;
    angle_and_gradient(u, g.counts[k], gt);
    gt -= ls.wg / ls.w;
    const double wk = w(k);
    const Vec7 du = cov * gt * wk;
    a(0) = g.level_share[l] * wk / ls.w - gbar.dot(du);
    a.tail<7>() = du;
    return true;
  }
};

// The covariance of the scaled coefficients split by the dwells' noise sources: source c
// contributes sum_k A_k A_k^T var_c,k; the sources sum to the whole covariance (var_k = 1 / w_k).
std::array<Eigen::Matrix<double, 8, 8>, 3> source_covariances(const Linear& lin) {
  std::array<Eigen::Matrix<double, 8, 8>, 3> out;
  for (auto& m : out) m.setZero();
  Eigen::Matrix<double, 8, 1> a;
  Vec7 gt;
  for (size_t k = 0; k < lin.g.size(); ++k) {
    if (!lin.weights(k, a, gt)) continue;
    const auto v = lin.w.parts(k);
    for (size_t c = 0; c < 3; ++c) out[c] += v[c] * a * a.transpose();
  }
  return out;
}

// The temperature's influence (TemperatureInfluence): shift = sum_k A_k x_k with x_k = T_k -
// T_ref, and kappa from the GLS of the residuals r_k on x'_k, the x_k less their level's mean and
// less gt_k . shift_u (the part the coefficients absorb), so kappa is what a fit with a temperature
// term would give. A dwell without a temperature counts as at T_ref.
TemperatureInfluence temperature_influence(const Linear& lin, double sigma_scale, size_t fit_dof) {
  TemperatureInfluence t;
  const GlsData& g = lin.g;
  if (!g.temperature_c || g.temperature_c->size() != g.size()) return t;
  const auto& temp = *g.temperature_c;
  double sw = 0, swt = 0;
  for (size_t k = 0; k < g.size(); ++k) {
    if (!std::isfinite(temp[k])) continue;
    sw += lin.w(k);
    swt += lin.w(k) * temp[k];
    ++t.dwells;
  }
  if (t.dwells == 0 || !(sw > 0)) return t;
  t.known = true;
  t.reference_c = swt / sw;
  const auto x = [&](size_t k) { return std::isfinite(temp[k]) ? temp[k] - t.reference_c : 0.0; };
  double sxx = 0;
  std::vector<double> level_wx(g.levels, 0.0);
  Eigen::Matrix<double, 8, 1> a;
  Vec7 gt;
  for (size_t k = 0; k < g.size(); ++k) {
    if (!lin.weights(k, a, gt)) continue;
    t.shift_scaled += a * x(k);
    level_wx[g.level_of(k)] += lin.w(k) * x(k);
    if (std::isfinite(temp[k])) sxx += lin.w(k) * x(k) * x(k);
  }
  t.spread_c = std::sqrt(sxx / sw);
  double srx = 0, sx2 = 0;
  for (size_t k = 0; k < g.size(); ++k) {
    const LevelSums& ls = lin.p.lv[g.level_of(k)];
    if (!(ls.w > 0)) continue;
    const double r = g.ref_arcsec(k) - angle_and_gradient(lin.u, g.counts[k], gt) - ls.we / ls.w;
    gt -= ls.wg / ls.w;
    const double xp = x(k) - level_wx[g.level_of(k)] / ls.w - gt.dot(t.shift_scaled.tail<7>());
    srx += lin.w(k) * r * xp;
    sx2 += lin.w(k) * xp * xp;
  }
  // r = ref - f0 - level: a reading larger by kappa x lowers r by as much.
  t.sensitivity_arcsec_per_c = sx2 > 1e-12 ? -srx / sx2 : 0.0;
  t.sensitivity_sigma = sx2 > 1e-12 ? sigma_scale / std::sqrt(sx2) : std::nan("");
  t.dof = fit_dof > 1 ? static_cast<double>(fit_dof - 1) : 1.0;
  return t;
}

}  // namespace

GlsFit refine_gls(const GlsData& g, const AxisCoeffs& start, double counts_lo, double counts_hi,
                  double remainder_sigmas) {
  GlsFit out;
  AxisCoeffs c0 = start;
  normalise(c0);
  c0[0] = 0;
  Scaled u = to_scaled(c0);
  // Weights from the start's slope (the count noise enters as slope x count error).
  const Weights w{&g, c0};
  Pass p = level_pass(g, w, u);
  u = minimise(g, w, u, p, out);
  // Back to the normalised form (positive frequencies, phases in (-pi, pi]) before the covariance.
  AxisCoeffs c = from_scaled(u);
  normalise(c);
  c[0] = 0;
  u = to_scaled(c);
  p = level_pass(g, w, u);
  const Solve s = solve_r(projected_r(g, w, u, p));

  // C1 = sum_g share_g level_g, level_g = weighted mean of (ref - f0) over its dwells.
  double c1 = 0, var_c1_noise = 0;
  Vec7 gbar = Vec7::Zero();
  for (size_t l = 0; l < g.levels; ++l) {
    const LevelSums& ls = p.lv[l];
    if (!(ls.w > 0) || !(g.level_share[l] > 0)) continue;
    const double a = g.level_share[l];
    c1 += a * ls.we / ls.w;
    gbar += a * ls.wg / ls.w;
    var_c1_noise += a * a / ls.w;
  }
  u[0] = c1;
  out.coeffs = from_scaled(u);

  out.chi2 = p.cost;
  const size_t params = 7 + g.levels;
  out.dof = g.size() > params ? g.size() - params : 0;
  out.reduced_chi2 = out.dof > 0 ? out.chi2 / static_cast<double>(out.dof) : std::nan("");
  double scale2 = 1.0;
  if (!g.noise_known) {
    scale2 = out.dof > 0 ? out.reduced_chi2 : std::nan("");
  } else if (out.dof > 0 &&
             out.reduced_chi2 > 1.0 + remainder_sigmas * std::sqrt(2.0 / static_cast<double>(out.dof))) {
    out.model_remainder = true;
    scale2 = out.reduced_chi2;
  }
  out.sigma_scale = std::sqrt(scale2);

  Uncertainty& un = out.uncertainty;
  Eigen::Matrix<double, 8, 8> cs = Eigen::Matrix<double, 8, 8>::Zero();
  cs.bottomRightCorner<7, 7>() = s.cov;
  const Vec7 cg = s.cov * gbar;
  cs(0, 0) = gbar.dot(cg) + var_c1_noise;
  cs.block<1, 7>(0, 1) = -cg.transpose();
  cs.block<7, 1>(1, 0) = -cg;
  un.covariance_scaled = cs * scale2;
  un.pseudo_inverse = s.deficient;
  un.residual_sigma_arcsec = out.sigma_scale;
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j < 8; ++j) un.covariance(i, j) = un.covariance_scaled(i, j) * kScaleFactor[i] * kScaleFactor[j];
  }
  for (int i = 0; i < 8; ++i) un.sigma[i] = std::sqrt(std::max(0.0, un.covariance(i, i)));
  const Linear lin{g, w, u, p, s.cov, gbar};
  if (g.noise_known) {
    un.source_covariance_scaled = source_covariances(lin);
    un.sources_known = true;
  }
  un.temperature = temperature_influence(lin, out.sigma_scale, out.dof);
  un.note = g.noise_known
                ? (out.model_remainder
                       ? "GLS of the changes (dwells with one level per joined set), noise model; chi2/dof "
                         "materially above 1 (a remainder the model does not fit): sigmas scaled by sqrt(chi2/dof)"
                       : "GLS of the changes (dwells with one level per joined set), covariance from the noise model")
                : "GLS of the changes with equal dwell weights (no noise known): covariance scaled by the residuals";
  if (s.deficient) un.note += "; J^T J rank deficient: pseudo-inverse";
  constexpr int kSteps = 200;
  for (int k = 0; k <= kSteps; ++k) {
    const double n = counts_lo + (counts_hi - counts_lo) * k / kSteps;
    double sig = angle_sigma_arcsec(un, out.coeffs, n);
    if (un.temperature.known) {
      sig = std::hypot(sig, angle_shift_arcsec(un.temperature.shift_scaled, out.coeffs, n) * un.temperature.u_per_shift());
    }
    if (sig > un.angle_sigma_max_arcsec) {
      un.angle_sigma_max_arcsec = sig;
      un.angle_sigma_at_counts = n;
    }
  }
  return out;
}

}  // namespace fpss::fit
