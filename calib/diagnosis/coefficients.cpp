// The coefficients candidate: the transfer function refitted to what the residual says each count reads.
#include <fmt/format.h>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "calib/diagnosis/model.h"
#include "calib/refine.h"
#include "calib/residuals.h"
#include "calib/units.h"

namespace fpss::diag {
namespace {

using Rows = std::vector<uint32_t>;
using ojson = nlohmann::ordered_json;

// ------------------------------------------------------------------ coefficients
// The sensor's transfer function differs from the model's: eq. 1 refitted per axis to what the
// residual says the angle at each count is. Scaled parameters keep the Jacobian balanced.
constexpr double kS = fit::kCountScale;  // the fit's one count scale (calib/residuals.h)

// The sinusoid frequencies the refit searches, rad/count: the published sets' span (1.0e-4 ..
// 5.5e-4 in the trustworthy ones) and more.
constexpr double kMinFrequency = 0.4e-4, kMaxFrequency = 8e-4;

// Eq. 1 in arcsec at count n. u: C1 arcsec, C2 arcsec per kS counts, C3 arcsec, C4 rad per kS
// counts, C5, C6, C7, C8.
// Its two sinusoids alone at x = n / kS (a joint fit solves C1 and C2 apart from them).
double sinusoids_arcsec(const std::array<double, 8>& u, double x) {
  return u[2] * std::sin(u[3] * x + u[4]) + u[5] * std::sin(u[6] * x + u[7]);
}
double eq1_arcsec(const std::array<double, 8>& u, double n) {
  const double x = n / kS;
  return u[0] + u[1] * x + sinusoids_arcsec(u, x);
}

// The fit's scaled coefficients (calib/residuals.h): u[0] C1 arcsec, u[1] C2 arcsec per kS counts,
// u[2] C3 arcsec, u[3] C4 rad per kS counts, u[4] C5, u[5..7] likewise.
std::array<double, 8> to_u(const AxisCoeffs& c) { return fit::to_scaled(c); }
AxisCoeffs from_u(const std::array<double, 8>& u) { return fit::from_scaled(u); }

double cost_of(const std::array<double, 8>& u, const std::vector<double>& n, const std::vector<double>& y) {
  double c = 0;
  for (size_t i = 0; i < n.size(); ++i) {
    const double e = eq1_arcsec(u, n[i]) - y[i];
    c += e * e;
  }
  return c;
}

// "The sensor is the model's unit, changed a little": a weak Gaussian prior on the sinusoids about
// the model's (amplitude 1-sigma half the model's amplitude plus 1 arcsec, frequency 10 %, phase
// 0.5 rad; C1 and C2, a bias and a scale, are free), in the units of the data's cost (weights =
// residual variance / sigma^2). Where the fit rows hold many angles it is negligible; where they
// hold a few levels only (a coarse grid, its one slew of an axis held out) eq. 1's eight
// parameters would otherwise interpolate them and swing between them.
fit::ScaledPrior sinusoid_prior(const std::array<double, 8>& model_u, double variance) {
  fit::ScaledPrior p;
  p.u0 = model_u;
  auto weight = [&](double sigma) { return variance / (sigma * sigma); };
  for (int k : {2, 5}) {
    p.weight[k] = weight(0.5 * std::abs(model_u[k]) + 1.0);
    p.weight[k + 1] = weight(0.1 * std::abs(model_u[k + 1]) + 1e-6);
    p.weight[k + 2] = weight(0.5);
  }
  return p;
}

// Eq. 1 refitted from u to the least-squares minimum on (n, y) by the calibrator's solver
// (fit::refine_rows: Ceres over the same functor), at most 100 iterations; u stays where it was
// when the solver cannot produce a solution.
void refine(std::array<double, 8>& u, const std::vector<double>& n, const std::vector<double>& y,
            const fit::ScaledPrior* prior = nullptr) {
  fit::RefineOptions o;
  o.max_iterations = 100;
  const fit::Refined r = fit::refine_rows(n, y, from_u(u), o, prior);
  if (r.usable) u = to_u(r.coeffs);
}

// What one axis's refit sees of the fit rows: the counts and the angle the sensor's true function
// gives there (the recorded angle less the other effects), on the two even strides the refit
// uses (its grid at most ~4000 rows, its refinement ~6000: eight coefficients are pinned far
// below the noise by that many), and the counts' range over all of them. Only the strided rows
// are held (all of them, two doubles a row, were 10 MB at 1M rows).
struct AxisRows {
  std::vector<double> n_grid, y_grid, n_fine, y_fine;
  size_t count = 0;
  double lo = 0, hi = 0;
};

AxisRows axis_rows(const Recording& r, int a, const Contribution& tg, const Rows& rows) {
  AxisRows s;
  s.count = rows.size();
  const size_t grid = std::max<size_t>(1, s.count / 4000), fine = std::max<size_t>(1, s.count / 6000);
  for (size_t k = 0; k < s.count; ++k) {
    const uint32_t i = rows[k];
    const double n = r.counts[a][i];
    if (k == 0 || n < s.lo) s.lo = n;
    if (k == 0 || n > s.hi) s.hi = n;
    if (k % grid != 0 && k % fine != 0) continue;
    const double y = r.meas(a, i) - tg.v[a][i];
    if (k % grid == 0) { s.n_grid.push_back(n); s.y_grid.push_back(y); }
    if (k % fine == 0) { s.n_fine.push_back(n); s.y_fine.push_back(y); }
  }
  return s;
}

// Of the refit from the grid's best node and the refit from the model, the one from the model
// unless the other fits significantly better: chi^2 falls by more than the 1 % point of chi^2 with
// 8 degrees of freedom (20.1; the two differ in all eight coefficients), in units of the better
// fit's residual variance. Over a field narrower than the sinusoids' periods eq. 1 is nearly
// degenerate: two sinusoids and a line trade against each other, and a solution far from the
// model can fit the fitted counts as well as one near it while parting from it beyond them. The
// sensor is the model's unit, changed a little, unless the data say otherwise.
const std::array<double, 8>& model_near_unless_worse(const std::array<double, 8>& from_grid,
                                                     const std::array<double, 8>& from_model,
                                                     const std::vector<double>& n, const std::vector<double>& y) {
  constexpr double kChi2_8dof_1pct = 20.09;
  const double c_grid = cost_of(from_grid, n, y), c_model = cost_of(from_model, n, y);
  if (!std::isfinite(c_grid)) return from_model;
  if (!std::isfinite(c_model)) return from_grid;
  const double var = std::min(c_grid, c_model) / std::max(1.0, static_cast<double>(n.size()) - 8.0);
  return c_model - c_grid > kChi2_8dof_1pct * var ? from_grid : from_model;
}

// Whether the fit rows reach enough of the field for eq. 1's eight parameters to be told apart
// freely: counts in at least 24 bins of 200 counts (about 20 arcsec; three bins a parameter). A
// grid of a few offsets without slews holds a few levels only; a free solution then not only
// interpolates them but flattens eq. 1 at each (its slope near zero there), which takes the
// sensor's count noise out of the residual: a chi^2 test counts that as a better fit, by far
// more than the parameters it spends.
bool covers_field(const std::vector<double>& n) {
  constexpr double kBinCounts = 200;
  constexpr size_t kMinBins = 24;
  std::vector<int64_t> bins;
  bins.reserve(n.size());
  for (double c : n) bins.push_back(static_cast<int64_t>(std::floor(c / kBinCounts)));
  std::sort(bins.begin(), bins.end());
  return static_cast<size_t>(std::unique(bins.begin(), bins.end()) - bins.begin()) >= kMinBins;
}

// Why a transfer function is not one the sensor family can have, or empty: sinusoids far beyond
// any the family shows (10x the model's largest, at least 200 arcsec), two that nearly cancel over
// the counts [lo, hi] (each more than 10x what they add up to there: an ill-conditioned refit),
// or a frequency outside the range the refit searches (a periodic error of another origin, such
// as a gimbal encoder's cyclic error of a few hundred arcsec period, 8e-4 .. 2e-3 rad a count).
std::string implausible(const AxisCoeffs& c, double model_amp_arcsec, double lo, double hi) {
  const double a3 = std::abs(rad_to_arcsec(c[2])), a6 = std::abs(rad_to_arcsec(c[5]));
  const double big = std::max(a3, a6), limit = std::max(200.0, 10.0 * model_amp_arcsec);
  if (big > limit) {
    return fmt::format("sinusoid amplitudes {:.0f} and {:.0f} arcsec, beyond physical plausibility (> {:.0f})", a3, a6,
                       limit);
  }
  double s2 = 0;
  constexpr int kSteps = 200;
  for (int k = 0; k <= kSteps; ++k) {
    const double nn = lo + (hi - lo) * k / kSteps;
    const double v = rad_to_arcsec(c[2] * std::sin(c[3] * nn + c[4]) + c[5] * std::sin(c[6] * nn + c[7]));
    s2 += v * v;
  }
  const double rms = std::sqrt(s2 / (kSteps + 1));
  if (big > 50.0 && std::min(a3, a6) > 10.0 * rms) {
    return fmt::format("two nearly cancelling sinusoids ({:.0f} and {:.0f} arcsec, together {:.1f} arcsec RMS): "
                       "an ill-conditioned refit",
                       a3, a6, rms);
  }
  for (int k : {3, 6}) {
    const double f = std::abs(c[k]);
    if (f < kMinFrequency || f > kMaxFrequency) {
      return fmt::format("a sinusoid of {:.2f} arcsec at {:.3g} rad/count, outside the {:.1e} .. {:.1e} the refit "
                         "searches (the published sets' frequencies and more): it stands in for a periodic error of "
                         "another origin",
                         std::abs(rad_to_arcsec(c[k - 1])), f, kMinFrequency, kMaxFrequency);
    }
  }
  return {};
}

// The larger of an axis's two sinusoid amplitudes, arcsec: the scale implausible() judges by.
double largest_amplitude_arcsec(const AxisCoeffs& c) {
  return std::max(std::abs(rad_to_arcsec(c[2])), std::abs(rad_to_arcsec(c[5])));
}

// One axis's refit, the residual variance its prior is scaled by, and whether the model-near
// solution was kept (a joint fit's later refits then keep the prior).
struct Refit {
  AxisCoeffs c{};
  double variance = 0;
  bool prior_kept = false;
};

// Variable projection: a log grid over both sinusoid frequencies (0.4e-4 .. 8e-4 rad/count, the
// published sets' span and more) with the linear parameters solved exactly at every node from one
// Gram matrix, then refined from the best node and from the model itself (model_near_unless_worse
// picks one).
Refit refit_axis(const AxisCoeffs& model, const AxisRows& s) {
  constexpr int kW = 24;
  std::vector<double> f(kW);
  for (int j = 0; j < kW; ++j) f[j] = kMinFrequency * std::pow(kMaxFrequency / kMinFrequency, j / (kW - 1.0)) * kS;
  const std::vector<double>& n = s.n_grid;
  const std::vector<double>& y = s.y_grid;
  const int dim = 2 + 2 * kW;
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(dim, dim);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(dim);
  Eigen::VectorXd row(dim);
  double yy = 0;
  for (size_t i = 0; i < n.size(); ++i) {
    const double x = n[i] / kS;
    row(0) = 1;
    row(1) = x;
    for (int j = 0; j < kW; ++j) {
      row(2 + 2 * j) = std::sin(f[j] * x);
      row(3 + 2 * j) = std::cos(f[j] * x);
    }
    G.selfadjointView<Eigen::Lower>().rankUpdate(row);
    b += row * y[i];
    yy += y[i] * y[i];
  }
  G = G.selfadjointView<Eigen::Lower>();
  double best = std::numeric_limits<double>::infinity();
  std::array<double, 8> best_u = to_u(model);
  for (int j = 0; j < kW; ++j) {
    for (int k = j + 2; k < kW; ++k) {
      const int idx[6] = {0, 1, 2 + 2 * j, 3 + 2 * j, 2 + 2 * k, 3 + 2 * k};
      Eigen::Matrix<double, 6, 6> g;
      Eigen::Matrix<double, 6, 1> v;
      for (int p = 0; p < 6; ++p) {
        v(p) = b(idx[p]);
        for (int q = 0; q < 6; ++q) g(p, q) = G(idx[p], idx[q]);
      }
      Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(g);
      if (ldlt.info() != Eigen::Success) continue;
      const Eigen::Matrix<double, 6, 1> xs = ldlt.solve(v);
      const double c = yy - xs.dot(v);
      if (c < best && std::isfinite(c)) {
        best = c;
        // a sin + b cos = hypot(a, b) sin(w x + atan2(b, a))
        best_u = {xs(0), xs(1), std::hypot(xs(2), xs(3)), f[j], std::atan2(xs(3), xs(2)),
                  std::hypot(xs(4), xs(5)), f[k], std::atan2(xs(5), xs(4))};
      }
    }
  }
  const std::vector<double>& nr = s.n_fine;
  const std::vector<double>& yr = s.y_fine;
  std::array<double, 8> from_model = to_u(model);
  refine(best_u, nr, yr);
  Refit out;
  out.variance = cost_of(best_u, nr, yr) / std::max(1.0, static_cast<double>(nr.size()) - 8.0);
  const fit::ScaledPrior prior = sinusoid_prior(to_u(model), out.variance);
  refine(from_model, nr, yr, &prior);
  // A free solution the sensor family cannot have is no rival to the model-near one (a second
  // effect in the rows, a time shift in slews, would otherwise pull it into one).
  const bool free_ok =
      covers_field(nr) && implausible(from_u(best_u), largest_amplitude_arcsec(model), s.lo, s.hi).empty();
  const std::array<double, 8>& kept = free_ok ? model_near_unless_worse(best_u, from_model, nr, yr) : from_model;
  out.c = from_u(kept);
  out.prior_kept = &kept == &from_model;
  return out;
}

// The sixths of the range as a list per axis, for GAP.json.
ojson sections_json(const RangeSections& s) {
  return {{"alpha", s[0]}, {"beta", s[1]}};
}

class Coefficients : public NamedCandidate<Coefficients> {
 public:
  Coefficients() : NamedCandidate("coefficients", 16) {}
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    const AxisCoeffs model[2] = {r.model.alpha, r.model.beta};
    for (int a = 0; a < 2; ++a) {
      model_amp_[a] = largest_amplitude_arcsec(model[a]);
      const AxisRows s = axis_rows(r, a, tg, rows);
      if (s.count < 8) {
        set_axis(a, model[a]);
      } else if (fitted_) {
        // Refitted again (a joint fit with another effect): the last solution is a good start.
        std::array<double, 8> u = to_u(c_[a]);
        const fit::ScaledPrior prior = sinusoid_prior(to_u(model[a]), variance_[a]);
        refine(u, s.n_fine, s.y_fine, prior_kept_[a] ? &prior : nullptr);
        set_axis(a, from_u(u));
      } else {
        const Refit f = refit_axis(model[a], s);
        set_axis(a, f.c);
        variance_[a] = f.variance;
        prior_kept_[a] = f.prior_kept;
      }
      if (s.count > 0) { lo_[a] = s.lo; hi_[a] = s.hi; }
    }
    sections_ = range_sections(r);
    half_range_arcsec_ = r.calibrated_range_arcsec;
    fitted_ = true;
  }
  // model(N) - refit(N); model(N) is the recording's measured angle (residual + reference), so
  // only the refit is evaluated (a joint fit rebuilds this contribution at every iteration).
  void contribute(const Recording& r, Contribution& out) const override {
    for (int a = 0; a < 2; ++a) {
      for (size_t i = 0; i < r.n; ++i) {
        out.v[a][i] = r.meas(a, i) - rad_to_arcsec(transfer_angle(c_[a].data(), static_cast<double>(r.counts[a][i])));
      }
    }
  }
  ojson params() const override { return {{"alpha", c_[0]}, {"beta", c_[1]}}; }
  // Eq. 1 is linear in C1 and C2: two columns an axis (zero on the other), so that a joint fit
  // solves them together with the other effect's linear parameters. Alternating a refit with a
  // drift or a temperature that the recording's order makes look like an offset or a slope in the
  // counts converges only geometrically (a ratio near 0.65 an iteration was seen: 20 iterations
  // left 3x the noise). The sinusoids stay with the refit: solved linearly at fixed frequencies,
  // two of them over a field shorter than their periods trade into large cancelling amplitudes.
  int columns() const override { return 4; }
  void column_values(const Recording& r, size_t i, int a, double* v) const override {
    // contribution = model(N) - eq. 1 = column_offset - C1 - C2 N - sinusoids
    v[0] = v[1] = v[2] = v[3] = 0.0;
    v[2 * a] = -1;
    v[2 * a + 1] = -static_cast<double>(r.counts[a][i]) / kS;
  }
  double column_offset(const Recording& r, size_t i, int a) const override {
    return r.meas(a, i) - sinusoids_arcsec(u_[a], static_cast<double>(r.counts[a][i]) / kS);
  }
  void set_linear(const std::vector<double>& w) override {
    for (int a = 0; a < 2; ++a) {
      std::array<double, 8> u = u_[a];
      u[0] = w[2 * a];
      u[1] = w[2 * a + 1];
      set_axis(a, from_u(u));
    }
  }
  void restart() override { fitted_ = false; }
  void set(const EffectParams& p) override {
    if (p.coefficients) { set_axis(0, p.coefficients->alpha); set_axis(1, p.coefficients->beta); }
  }
  // Ill-conditioned or implausible (implausible(), over the counts fitted): the refit then stands
  // in for something eq. 1 is not.
  std::string degenerate() const override {
    if (!fitted_) return {};
    const char* axis[2] = {"alpha", "beta"};
    for (int a = 0; a < 2; ++a) {
      const std::string why = implausible(c_[a], model_amp_[a], lo_[a], hi_[a]);
      if (!why.empty()) return fmt::format("{}: {}", axis[a], why);
    }
    return {};
  }
  ojson notes() const override {
    if (!fitted_) return ojson::object();
    return {{"params", "the sensor's transfer function (paper eq. 1) refitted per axis on the fit rows: C1..C8, "
                       "radians and counts, as in a coefficient file (the emulator's coefficients effect)"},
            {"counts_range", {{"alpha", {lo_[0], hi_[0]}}, {"beta", {lo_[1], hi_[1]}}}},
            {"range_sections", sections_json(sections_)},
            {"range_sections_note", fmt::format("the sixths of the calibrated range ±{:g} arcsec (pitch for alpha, yaw "
                                                "for beta) the recordings' rows reach: the refit is measured there and "
                                                "extrapolated elsewhere", half_range_arcsec_)}};
  }

 private:
  void set_axis(int a, const AxisCoeffs& c) {
    c_[a] = c;
    u_[a] = to_u(c);
  }

  AxisCoeffs c_[2]{};
  std::array<double, 8> u_[2]{};  // c_ scaled (eq1_arcsec), for the columns
  double lo_[2] = {0, 0}, hi_[2] = {0, 0};
  double model_amp_[2] = {0, 0};
  double variance_[2] = {0, 0};
  RangeSections sections_{};
  double half_range_arcsec_ = 0;
  bool prior_kept_[2] = {false, false};
  bool fitted_ = false;
};

}  // namespace

RangeSections range_sections(const Recording& r) {
  RangeSections out{};
  const double R = r.calibrated_range_arcsec, width = 2 * R / kRangeSections;
  if (!(R > 0)) return out;
  for (size_t i = 0; i < r.n; ++i) {
    if (r.use[i] == Use::excluded) continue;  // the fit and held-out rows are all the others
    for (int a = 0; a < 2; ++a) {
      const double x = r.ref[a][i];
      if (!(std::abs(x) <= R * (1 + 1e-9))) continue;
      out[a][std::clamp(static_cast<int>(std::floor((x + R) / width)), 0, kRangeSections - 1)] = true;
    }
  }
  return out;
}

std::unique_ptr<Candidate> make_coefficients_candidate() { return std::make_unique<Coefficients>(); }

}  // namespace fpss::diag
