#include "calib/refine.h"

#include <ceres/ceres.h>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>

#include "calib/units.h"

namespace fpss::fit {
namespace {

// Rows a Problem reads; the functors point into these, so they outlive the Problem.
struct RowView {
  const double* n_plus;
  const double* n_minus;
  const double* y;
  size_t count;
};

struct Strided {
  std::vector<double> n_plus, n_minus, y;
};

RowView view_of(const AxisData& d, double fraction, Strided& keep) {
  if (fraction >= 1.0 && d.changes.empty()) {
    return {d.n_plus.data(), d.differences ? d.n_minus.data() : nullptr, d.y_arcsec.data(), d.rows()};
  }
  // Rows held as dwell pairs (or a subset): gathered, as Ceres reads contiguous rows.
  for (size_t i = 0; i < d.rows(); ++i) {
    if (!in_spread_subset(i, fraction)) continue;
    keep.n_plus.push_back(d.row_n_plus(i));
    if (d.differences) keep.n_minus.push_back(d.row_n_minus(i));
    keep.y.push_back(d.row_y_arcsec(i));
  }
  return {keep.n_plus.data(), d.differences ? keep.n_minus.data() : nullptr, keep.y.data(), keep.y.size()};
}

// The parameter block is u[1..7] (differences) or u[0..7] (absolute); see residuals.h.
double* block_of(bool differences, Scaled& u) { return differences ? u.data() + 1 : u.data(); }

void build_problem(ceres::Problem& problem, const RowView& v, bool differences, Scaled& u, int per_block) {
  double* block = block_of(differences, u);
  for (size_t i = 0; i < v.count; i += static_cast<size_t>(per_block)) {
    const int m = static_cast<int>(std::min<size_t>(per_block, v.count - i));
    ceres::CostFunction* cf = nullptr;
    if (differences) {
      cf = new ceres::AutoDiffCostFunction<DifferenceResiduals, ceres::DYNAMIC, 7>(
          new DifferenceResiduals{v.n_plus + i, v.n_minus + i, v.y + i, m}, m);
    } else {
      cf = new ceres::AutoDiffCostFunction<AbsoluteResiduals, ceres::DYNAMIC, 8>(
          new AbsoluteResiduals{v.n_plus + i, v.y + i, m}, m);
    }
    problem.AddResidualBlock(cf, nullptr, block);
  }
}

// Ceres logs a rank-deficient first attempt as an error; the fallback below handles it and
// says so in the report, so the log line would only alarm. Restores glog's level on exit.
class QuietGlog {
 public:
  QuietGlog() : saved_(FLAGS_minloglevel) { FLAGS_minloglevel = google::GLOG_FATAL; }
  ~QuietGlog() { FLAGS_minloglevel = saved_; }
  QuietGlog(const QuietGlog&) = delete;
  QuietGlog& operator=(const QuietGlog&) = delete;

 private:
  int saved_;
};

double wrap_phase(double p) {
  constexpr double kPi = std::numbers::pi;
  p = std::remainder(p, 2 * kPi);
  return p <= -kPi ? p + 2 * kPi : p;
}

// The same function with positive frequencies and phases in (-pi, pi]: sin(-wN + p) = -sin(wN - p).
void normalise(AxisCoeffs& c) {
  for (int s : {2, 5}) {
    if (c[s + 1] < 0) {
      c[s + 1] = -c[s + 1];
      c[s] = -c[s];
      c[s + 2] = -c[s + 2];
    }
    c[s + 2] = wrap_phase(c[s + 2]);
  }
}

// d(angle in arcsec at n)/du over the block's parameters (the first p entries).
Eigen::Matrix<double, 8, 1> angle_gradient(const Scaled& u, bool differences, double n) {
  using J = ceres::Jet<double, 8>;
  J uj[8];
  const int p = differences ? 7 : 8;
  const int first = differences ? 1 : 0;
  for (int i = 0; i < 8; ++i) uj[i] = J(u[i]);
  for (int i = 0; i < p; ++i) uj[first + i].v[i] = 1.0;
  const std::array<J, 8> c = arcsec_coeffs(uj + 1, differences ? J(0.0) : uj[0]);
  const J a = transfer_angle(c.data(), n);
  Eigen::Matrix<double, 8, 1> g = Eigen::Matrix<double, 8, 1>::Zero();
  for (int i = 0; i < p; ++i) g(i) = a.v[i];
  return g;
}

}  // namespace

double null_condition_c1(const AxisData& d, const AxisCoeffs& c) {
  AxisCoeffs g = c;
  g[0] = 0;
  return arcsec_to_rad(d.null_ref_arcsec()) - transfer_angle(g.data(), d.null_counts());
}

Refined refine_axis(const AxisData& d, const AxisCoeffs& start, const RefineOptions& opts, double fraction) {
  Strided keep;
  const RowView v = view_of(d, fraction, keep);
  AxisCoeffs s = start;
  if (d.differences) s[0] = 0;
  Scaled u = to_scaled(s);
  ceres::Problem::Options po;
  po.enable_fast_removal = false;
  ceres::Problem problem(po);
  build_problem(problem, v, d.differences, u, opts.rows_per_block);

  ceres::Solver::Options so;
  // QR, not normal equations: the coefficients are strongly correlated over +-0.4 deg and
  // squaring the Jacobian's condition number would cost the digits the fit needs.
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = opts.max_iterations;
  so.function_tolerance = 1e-12;
  so.gradient_tolerance = 1e-14;
  so.parameter_tolerance = 1e-12;
  so.num_threads = std::max(1, opts.threads);
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);

  Refined r;
  r.rows = v.count;
  r.initial_cost = summary.initial_cost;
  r.final_cost = summary.final_cost;
  r.iterations = static_cast<int>(summary.iterations.size());
  r.usable = summary.IsSolutionUsable() && std::isfinite(summary.final_cost);
  r.converged = summary.termination_type == ceres::CONVERGENCE;
  r.brief = summary.BriefReport();
  r.coeffs = from_scaled(u);
  normalise(r.coeffs);
  if (d.differences) r.coeffs[0] = null_condition_c1(d, r.coeffs);
  return r;
}

Uncertainty uncertainty(const AxisData& d, const AxisCoeffs& fit, const RefineOptions& opts) {
  Strided keep;
  const RowView v = view_of(d, 1.0, keep);
  AxisCoeffs s = fit;
  if (d.differences) s[0] = 0;
  Scaled u = to_scaled(s);
  ceres::Problem problem;
  build_problem(problem, v, d.differences, u, opts.rows_per_block);
  const int p = static_cast<int>(d.parameters());
  double* block = block_of(d.differences, u);

  Uncertainty out;
  double sum_sq = 0;
  for (size_t i = 0; i < d.rows(); ++i) {
    const double r = residual_arcsec(d, fit, i);
    sum_sq += r * r;
  }
  const double dof = static_cast<double>(d.rows()) - p;
  out.residual_sigma_arcsec = dof > 0 ? std::sqrt(sum_sq / dof) : 0.0;

  Eigen::Matrix<double, 8, 8, Eigen::RowMajor> cov_u = Eigen::Matrix<double, 8, 8, Eigen::RowMajor>::Zero();
  {
    ceres::Covariance::Options co;
    co.algorithm_type = ceres::DENSE_SVD;
    co.num_threads = std::max(1, opts.threads);
    co.null_space_rank = 0;  // fail on rank deficiency, then fall back below and say so
    ceres::Covariance cov(co);
    const std::vector<const double*> blocks = {block};
    bool ok;
    {
      QuietGlog quiet;
      ok = cov.Compute(blocks, &problem);
    }
    if (ok) {
      cov.GetCovarianceMatrix(blocks, cov_u.data());
      out.note = "covariance from the Jacobian (Ceres, dense SVD)";
    } else {
      ceres::Covariance::Options co2 = co;
      co2.null_space_rank = -1;  // Moore-Penrose: drop directions the data cannot see
      ceres::Covariance cov2(co2);
      if (cov2.Compute(blocks, &problem)) {
        cov2.GetCovarianceMatrix(blocks, cov_u.data());
        out.pseudo_inverse = true;
        out.note =
            "J^T J is rank deficient at this fit (strongly correlated coefficients): covariance is its "
            "pseudo-inverse; coefficient sigmas along the unseen directions are not meaningful, the "
            "angle uncertainty is";
      } else {
        out.note = "covariance could not be computed";
        std::fill(out.sigma.begin(), out.sigma.end(), std::numeric_limits<double>::quiet_NaN());
        out.angle_sigma_max_arcsec = std::numeric_limits<double>::quiet_NaN();
        return out;
      }
    }
  }
  // GetCovarianceMatrix packs the p x p block densely at the start of the buffer.
  Eigen::MatrixXd cu = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
                           cov_u.data(), p, p) *
                       (out.residual_sigma_arcsec * out.residual_sigma_arcsec);

  // C = function of u: diagonal scaling, and for the differences method C1 through the null condition.
  const Eigen::Matrix<double, 8, 1> g_null = d.differences ? angle_gradient(u, true, d.null_counts())
                                                           : Eigen::Matrix<double, 8, 1>::Zero();
  Eigen::MatrixXd jc = Eigen::MatrixXd::Zero(8, p);
  const int first = d.differences ? 1 : 0;
  for (int i = 0; i < p; ++i) jc(first + i, i) = kScaleFactor[first + i];
  if (d.differences) {
    for (int i = 0; i < p; ++i) jc(0, i) = -g_null(i) / kArcsecPerRad;
  }
  out.covariance = jc * cu * jc.transpose();
  {
    // u[0] = C1 in arcsec: fitted (absolute) or through the null condition (differences).
    Eigen::MatrixXd ju = Eigen::MatrixXd::Zero(8, p);
    for (int i = 0; i < p; ++i) ju(first + i, i) = 1.0;
    if (d.differences) {
      for (int i = 0; i < p; ++i) ju(0, i) = -g_null(i);
    }
    out.covariance_scaled = ju * cu * ju.transpose();
  }
  for (int i = 0; i < 8; ++i) out.sigma[i] = std::sqrt(std::max(0.0, out.covariance(i, i)));

  constexpr int kSteps = 200;
  for (int s2 = 0; s2 <= kSteps; ++s2) {
    const double n = d.counts_lo + (d.counts_hi - d.counts_lo) * s2 / kSteps;
    const Eigen::VectorXd gr = (angle_gradient(u, d.differences, n) - g_null).head(p);
    const double sig = std::sqrt(std::max(0.0, gr.dot(cu * gr)));
    if (sig > out.angle_sigma_max_arcsec) {
      out.angle_sigma_max_arcsec = sig;
      out.angle_sigma_at_counts = n;
    }
  }
  return out;
}

}  // namespace fpss::fit

namespace fpss::fit {

double angle_sigma_arcsec(const Uncertainty& u, const AxisCoeffs& fit, double counts) {
  const Eigen::Matrix<double, 8, 1> g = angle_gradient(to_scaled(fit), false, counts);
  return std::sqrt(std::max(0.0, g.dot(u.covariance_scaled * g)));
}

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

// f0 and its gradient as the iteration sees it: over u[1..7] (C3 sin(C4 N + C5), the reported form)
// or, while iterating, in the Cartesian form a sin(w x) + b cos(w x) (x = N / kCountScale), where
// the amplitudes enter linearly: a slow sinusoid over less than half its period is nearly a
// polynomial, and in (amplitude, phase) its valley is long and curved (Gauss-Newton then crawls
// along it for hundreds of iterations); in (a, b) only the frequencies are nonlinear.
struct Model {
  bool cartesian = false;
  Scaled u{};
  // slope, a1, b1, a2, b2 (the linear parameters, arcsec), then w1, w2 (rad per kCountScale counts)
  Vec7 v = Vec7::Zero();

  static Model polar(const Scaled& u) {
    Model m;
    m.u = u;
    return m;
  }
  static Model from_polar(const Scaled& u) {
    Model m;
    m.cartesian = true;
    m.v << u[1], u[2] * std::cos(u[4]), u[2] * std::sin(u[4]), u[5] * std::cos(u[7]), u[5] * std::sin(u[7]), u[3], u[6];
    return m;
  }
  Scaled to_polar() const {
    if (!cartesian) return u;
    Scaled out{};
    out[1] = v(0);
    out[2] = std::hypot(v(1), v(2));
    out[3] = v(5);
    out[4] = std::atan2(v(2), v(1));
    out[5] = std::hypot(v(3), v(4));
    out[6] = v(6);
    out[7] = std::atan2(v(4), v(3));
    return out;
  }
  double operator()(double n, Vec7& grad) const {
    if (!cartesian) return angle_and_gradient(u, n, grad);
    const double x = n / kCountScale;
    const double s1 = std::sin(v(5) * x), c1 = std::cos(v(5) * x);
    const double s2 = std::sin(v(6) * x), c2 = std::cos(v(6) * x);
    grad << x, s1, c1, s2, c2, x * (v(1) * c1 - v(2) * s1), x * (v(3) * c2 - v(4) * s2);
    return v(0) * x + v(1) * s1 + v(2) * c1 + v(3) * s2 + v(4) * c2;
  }
};

// The dwells' weights, 1 / variance in arcsec^-2, from the start's slope, computed when read (no
// array per dwell); float, as they were kept.
struct Weights {
  const GlsData* g;
  AxisCoeffs c0;
  float operator()(size_t k) const {
    if (!g->noise_known) return 1.0f;
    const double slope = rad_to_arcsec(transfer_slope(c0.data(), g->counts[k]));
    return static_cast<float>(1.0 / std::max(1e-30, g->var_ref_arcsec2(k) + slope * slope * g->var_counts2[k]));
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

Pass level_pass(const GlsData& g, const Weights& w, const Model& f) {
  Pass p;
  p.lv.assign(g.levels, LevelSums{});
  Vec7 gr;
  for (size_t k = 0; k < g.size(); ++k) {
    const double e = g.ref_arcsec(k) - f(g.counts[k], gr);
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
Eigen::Matrix<double, 8, 8> projected_r(const GlsData& g, const Weights& w, const Model& f,
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
    const double e = g.ref_arcsec(k) - f(g.counts[k], gr);
    const double sw = std::sqrt(w(k));
    stack.row(rows).head<7>() = (sw * (gr - l.wg / l.w)).transpose();
    const double res = -sw * (e - l.we / l.w);
    stack(rows, 7) = res;
    if (++rows == kChunk) reduce();
  }
  if (rows > 0 || !have_r) reduce();
  return r;
}

// Pseudo-inverse of R11^T R11 and the Gauss-Newton step -R11^+ z.
struct Solve {
  Mat7 cov = Mat7::Zero();
  Vec7 step = Vec7::Zero();
  bool deficient = false;
};
Solve solve_r(const Eigen::Matrix<double, 8, 8>& r) {
  Solve s;
  const Mat7 r11 = r.topLeftCorner<7, 7>();
  const Vec7 z = r.topRightCorner<7, 1>();
  Eigen::JacobiSVD<Mat7> svd(r11, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const auto& sv = svd.singularValues();
  const double tol = 1e-10 * sv(0);
  Vec7 inv = Vec7::Zero();
  for (int i = 0; i < 7; ++i) {
    if (sv(i) > tol) inv(i) = 1.0 / sv(i);
    else s.deficient = true;
  }
  const Mat7 v = svd.matrixV();
  s.cov = v * inv.cwiseAbs2().asDiagonal() * v.transpose();
  s.step = -(v * inv.asDiagonal() * svd.matrixU().transpose() * z);
  return s;
}

// The linear parameters (slope and both sinusoids' a, b) exactly at their optimum for the current
// frequencies: the leading 5 x 5 block of the projected QR, as the model is linear in them.
void solve_linear(const GlsData& g, const Weights& w, Model& f, Pass& p) {
  const Eigen::Matrix<double, 8, 8> rl = projected_r(g, w, f, p);
  const Eigen::Matrix<double, 5, 5> r_lin = rl.topLeftCorner<5, 5>();
  Eigen::JacobiSVD<Eigen::Matrix<double, 5, 5>> svd(r_lin, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix<double, 5, 1> inv = Eigen::Matrix<double, 5, 1>::Zero();
  for (int i = 0; i < 5; ++i) {
    if (svd.singularValues()(i) > 1e-10 * svd.singularValues()(0)) inv(i) = 1.0 / svd.singularValues()(i);
  }
  Model lin = f;
  lin.v.head<5>() -= svd.matrixV() * inv.asDiagonal() * svd.matrixU().transpose() * rl.block<5, 1>(0, 7);
  Pass q = level_pass(g, w, lin);
  if (q.cost < p.cost) {
    f = lin;
    p = std::move(q);
  }
}

// Moves `f` (Cartesian) to the minimum; `p` is its pass. Sets out.iterations and out.converged.
void minimise(const GlsData& g, const Weights& w, Model& f, Pass& p, GlsFit& out) {
  // Levenberg-Marquardt on the projected problem: Gauss-Newton steps while they lower the cost,
  // damped (Marquardt's diagonal scaling) when they do not. A slow sinusoid over less than half its
  // period is nearly a polynomial, and the cost is flat and curved along its frequency: undamped
  // steps halved along one direction stopped at a 30-iteration cap short of the minimum on 23 of 200
  // yaw fits of Table A-5 FPSS2's grid (docs/calibration.md). Converged when the whole Gauss-Newton step
  // would gain less than kGainTolerance of chi^2 (|z|^2, the residuals' part in the Jacobian's column
  // space), or less than kGainOfResidualVariance of one residual's variance (cost / dof: a change of
  // the transfer function of about a hundredth of its sigma), or no step lowers the cost.
  constexpr int kMaxIterations = 300;
  constexpr double kGainTolerance = 1e-10;
  constexpr double kGainOfResidualVariance = 1e-4;
  const double dof = static_cast<double>(std::max<size_t>(1, g.size() > 7 + g.levels ? g.size() - 7 - g.levels : 1));
  double lambda = 0;
  for (int it = 0; it < kMaxIterations; ++it) {
    out.iterations = it + 1;
    // Variable projection: the linear parameters first go exactly to their optimum at these
    // frequencies (the QR's leading 5 x 5 block: the model is linear in them), so the step below
    // only has the frequencies' flat but short valley to follow.
    solve_linear(g, w, f, p);
    const Eigen::Matrix<double, 8, 8> r = projected_r(g, w, f, p);
    const Vec7 z = r.topRightCorner<7, 1>();
    if (z.squaredNorm() <= std::max(kGainTolerance, kGainOfResidualVariance / dof) * p.cost || p.cost <= 1e-300) {
      out.converged = true;
      break;
    }
    const Solve gn = solve_r(r);
    const Mat7 r11 = r.topLeftCorner<7, 7>();
    const Mat7 a = r11.transpose() * r11;
    const Vec7 rhs = -(r11.transpose() * z);
    const Vec7 diag = a.diagonal().cwiseMax(1e-12 * a.diagonal().maxCoeff());
    bool moved = false;
    for (int tries = 0; tries < 24; ++tries) {
      const Vec7 step = lambda == 0 ? gn.step : Vec7((a + lambda * Mat7(diag.asDiagonal())).ldlt().solve(rhs));
      Model trial = f;
      trial.v += step;
      Pass q = level_pass(g, w, trial);
      if (q.cost < p.cost) {
        f = trial;
        p = std::move(q);
        moved = true;
        lambda = lambda < 1e-7 ? 0 : lambda / 3;
        break;
      }
      lambda = lambda == 0 ? 1e-6 : lambda * 4;
    }
    if (!moved) {
      out.converged = true;  // no step lowers the cost: at the minimum to round-off
      break;
    }
  }
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
  Model f = Model::from_polar(u);
  Pass p = level_pass(g, w, f);
  minimise(g, w, f, p, out);
  u = f.to_polar();
  // Back to the normalised form (positive frequencies, phases in (-pi, pi]) before the covariance.
  AxisCoeffs c = from_scaled(u);
  normalise(c);
  c[0] = 0;
  u = to_scaled(c);
  p = level_pass(g, w, Model::polar(u));
  const Solve s = solve_r(projected_r(g, w, Model::polar(u), p));

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
    const double sig = angle_sigma_arcsec(un, out.coeffs, n);
    if (sig > un.angle_sigma_max_arcsec) {
      un.angle_sigma_max_arcsec = sig;
      un.angle_sigma_at_counts = n;
    }
  }
  return out;
}

}  // namespace fpss::fit
