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

// Levenberg-Marquardt on the rows' problem (u its parameters); the report with u as coefficients.
Refined solve_rows(ceres::Problem& problem, const RefineOptions& opts, const Scaled& u) {
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
  r.initial_cost = summary.initial_cost;
  r.final_cost = summary.final_cost;
  r.iterations = static_cast<int>(summary.iterations.size());
  r.usable = summary.IsSolutionUsable() && std::isfinite(summary.final_cost);
  r.converged = summary.termination_type == ceres::CONVERGENCE;
  r.brief = summary.BriefReport();
  r.coeffs = from_scaled(u);
  return r;
}

// sqrt(weight) (u - u0): the prior as residuals. Parameter block: u[0..7].
struct PriorResiduals {
  ScaledPrior prior;
  template <typename T>
  bool operator()(const T* u, T* r) const {
    for (int i = 0; i < 8; ++i) r[i] = (u[i] - T(prior.u0[i])) * std::sqrt(prior.weight[i]);
    return true;
  }
};

}  // namespace

namespace {

double wrap_phase(double p) {
  constexpr double kPi = std::numbers::pi;
  p = std::remainder(p, 2 * kPi);
  return p <= -kPi ? p + 2 * kPi : p;
}

}  // namespace

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

Refined refine_rows(const std::vector<double>& counts, const std::vector<double>& angle_arcsec, const AxisCoeffs& start,
                    const RefineOptions& opts, const ScaledPrior* prior) {
  const RowView v{counts.data(), nullptr, angle_arcsec.data(), std::min(counts.size(), angle_arcsec.size())};
  Scaled u = to_scaled(start);
  ceres::Problem problem;
  build_problem(problem, v, false, u, opts.rows_per_block);
  if (prior) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<PriorResiduals, 8, 8>(new PriorResiduals{*prior}), nullptr,
                             u.data());
  }
  Refined r = solve_rows(problem, opts, u);
  r.rows = v.count;
  return r;
}

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

  Refined r = solve_rows(problem, opts, u);
  r.rows = v.count;
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

Eigen::Matrix<double, 8, 1> dwell_gradient(const AxisCoeffs& c, double counts) {
  using J = ceres::Jet<double, 8>;
  const Scaled u = to_scaled(c);
  J u27[7];
  for (int i = 0; i < 7; ++i) u27[i] = J(u[1 + i], i);
  const J a = DwellLevelResidual{counts, 0.0, 1.0}(u27, J(u[0], 7));
  return a.v;
}

double angle_sigma_arcsec(const Eigen::Matrix<double, 8, 8>& covariance_scaled, const AxisCoeffs& fit, double counts) {
  const Eigen::Matrix<double, 8, 1> g = angle_gradient(to_scaled(fit), false, counts);
  return std::sqrt(std::max(0.0, g.dot(covariance_scaled * g)));
}

double angle_sigma_arcsec(const Uncertainty& u, const AxisCoeffs& fit, double counts) {
  return angle_sigma_arcsec(u.covariance_scaled, fit, counts);
}

double angle_shift_arcsec(const Eigen::Matrix<double, 8, 1>& shift_scaled, const AxisCoeffs& fit, double counts) {
  return angle_gradient(to_scaled(fit), false, counts).dot(shift_scaled);
}

}  // namespace fpss::fit
