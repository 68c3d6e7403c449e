// The grid stage (variable projection), the residual functors and the Ceres refinement.
#include "calib/varpro.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "calib/refine.h"
#include "calib/residuals.h"
#include "calib/units.h"

namespace fpss::fit {
namespace {

// Changes null -> offset for offsets spread over +-0.42 deg, counts exact (no noise).
AxisData changes_of(const AxisCoeffs& truth, int offsets, double noise_arcsec = 0, uint64_t seed = 1) {
  const AxisModel m(truth);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  AxisData d;
  const double n0 = m.counts_for_angle(0.0, -20000, 20000);
  for (int i = 0; i < offsets; ++i) {
    const double ang = arcsec_to_rad(-1512.0 + 3024.0 * i / (offsets - 1));
    const double n = m.counts_for_angle(ang, -20000, 20000);
    d.n_plus.push_back(n);
    d.n_minus.push_back(n0);
    d.y_arcsec.push_back(rad_to_arcsec(ang) + noise_arcsec * g(rng));
    d.cover(n, rad_to_arcsec(ang));
  }
  d.null_counts_sum = n0;
  d.null_ref_arcsec_sum = 0;
  d.null_dwells = 1;
  d.cover(n0, 0);
  return d;
}

double max_diff_arcsec(const AxisCoeffs& a, const AxisCoeffs& b, double lo, double hi) {
  double worst = 0;
  for (int i = 0; i <= 400; ++i) {
    const double n = lo + (hi - lo) * i / 400;
    worst = std::max(worst, std::abs(rad_to_arcsec(transfer_angle(a.data(), n) - transfer_angle(b.data(), n))));
  }
  return worst;
}

// Frequencies on grid nodes (1.7e-4 and 3.3e-4), one of them negative as some published sets print.
const AxisCoeffs kOnGrid = {-4e-4, 5.3e-7, 3e-5, 1.7e-4, 0.4, -2e-5, -3.3e-4, 1.1};

TEST(FrequencyGram, ExactDataIsFitExactlyAtItsNode) {
  const AxisData d = changes_of(kOnGrid, 41);
  FrequencyGram g(GridConfig{}, true);
  g.add(d.n_plus.data(), d.n_minus.data(), d.y_arcsec.data(), d.rows());
  EXPECT_EQ(g.rows(), 41u);
  EXPECT_EQ(g.frequencies(), 66u);  // 0.5e-4 .. 7e-4 in 1e-5 steps
  const auto best = g.best_nodes(3);
  ASSERT_FALSE(best.empty());
  EXPECT_NEAR(g.frequency(best[0].j), 1.7e-4, 1e-12);
  EXPECT_NEAR(g.frequency(best[0].k), 3.3e-4, 1e-12);
  EXPECT_LT(std::sqrt(best[0].cost / 41), 1e-6);  // arcsec rms
  AxisCoeffs c = g.coefficients(best[0]);
  c[0] = kOnGrid[0];  // C1 cancels in changes
  EXPECT_LT(max_diff_arcsec(c, kOnGrid, d.counts_lo, d.counts_hi), 1e-6);
  EXPECT_GT(c[3], 0);
  EXPECT_GT(c[6], 0);  // |w| searched: the negative frequency comes back positive, same function
  for (size_t i = 1; i < best.size(); ++i) EXPECT_GE(best[i].cost, best[i - 1].cost);
}

TEST(FrequencyGram, RowByRowEqualsChunked) {
  const AxisData d = changes_of(kOnGrid, 600, 0.05);
  FrequencyGram a(GridConfig{}, true), b(GridConfig{}, true);
  a.add(d.n_plus.data(), d.n_minus.data(), d.y_arcsec.data(), d.rows());
  for (size_t i = 0; i < d.rows(); ++i) b.add(d.n_plus[i], d.n_minus[i], d.y_arcsec[i]);
  for (auto [j, k] : {std::pair{0, 10}, {12, 28}, {30, 65}}) {
    const auto na = a.solve(j, k), nb = b.solve(j, k);
    ASSERT_TRUE(na.valid());
    EXPECT_NEAR(na.cost, nb.cost, 1e-9 * na.cost + 1e-12);
  }
}

TEST(FrequencyGram, TooFewRowsOrEqualFrequenciesAreInvalidNodes) {
  const AxisData d = changes_of(kOnGrid, 5);
  FrequencyGram g(GridConfig{}, true);
  g.add(d.n_plus.data(), d.n_minus.data(), d.y_arcsec.data(), d.rows());
  EXPECT_FALSE(g.solve(3, 20).valid());  // 5 rows for 5 unknowns: no residual to judge by
  EXPECT_TRUE(g.best_nodes(4).empty());
  const AxisData e = changes_of(kOnGrid, 30);
  FrequencyGram h(GridConfig{}, true);
  h.add(e.n_plus.data(), e.n_minus.data(), e.y_arcsec.data(), e.rows());
  EXPECT_FALSE(h.solve(7, 7).valid());  // one frequency twice: singular
}

TEST(Residuals, FunctorsMatchTheTransferFunction) {
  const AxisData d = changes_of(kOnGrid, 9, 0.1);
  Scaled u = to_scaled(kOnGrid);
  std::vector<double> r(d.rows());
  DifferenceResiduals f{d.n_plus.data(), d.n_minus.data(), d.y_arcsec.data(), static_cast<int>(d.rows())};
  ASSERT_TRUE(f(u.data() + 1, r.data()));
  for (size_t i = 0; i < d.rows(); ++i) EXPECT_NEAR(r[i], residual_arcsec(d, kOnGrid, i), 1e-9);

  AxisData a;
  a.differences = false;
  a.n_plus = d.n_plus;
  for (double n : a.n_plus) a.y_arcsec.push_back(AxisModel(kOnGrid).angle_arcsec(n) + 0.25);
  AbsoluteResiduals fa{a.n_plus.data(), a.y_arcsec.data(), static_cast<int>(a.rows())};
  ASSERT_TRUE(fa(u.data(), r.data()));
  for (size_t i = 0; i < a.rows(); ++i) EXPECT_NEAR(r[i], -0.25, 1e-9);
  // Scaling round trip.
  const AxisCoeffs back = from_scaled(u);
  for (int i = 0; i < 8; ++i) EXPECT_NEAR(back[i], kOnGrid[i], 1e-15 * std::abs(kOnGrid[i]) + 1e-300);
}

TEST(Refine, ConvergesFromANearbyStartAndSetsC1ByTheNullCondition) {
  const AxisCoeffs truth = {2e-4, 5.31e-7, -3.3e-5, 1.63e-4, -1.7, -6.9e-6, 3.72e-4, 1.6};  // Table A-2 FPSS2 alpha
  const AxisData d = changes_of(truth, 40);
  AxisCoeffs start = truth;
  start[3] *= 1.03;
  start[6] *= 0.98;
  start[4] += 0.1;
  const Refined r = refine_axis(d, start, RefineOptions{});
  ASSERT_TRUE(r.usable);
  EXPECT_LT(r.final_cost, 1e-10);
  EXPECT_LT(max_diff_arcsec(r.coeffs, truth, d.counts_lo, d.counts_hi), 1e-4);
  // The null dwell sits at angle 0 by construction.
  EXPECT_NEAR(AxisModel(r.coeffs).angle_arcsec(d.null_counts()), 0.0, 1e-9);
  EXPECT_NE(r.brief.find("CONVERGENCE"), std::string::npos) << r.brief;
}

TEST(Refine, AngleUncertaintyMatchesTheScatterOfRepeatedFits) {
  // The covariance's 1-sigma of the angle against the scatter of fits to independent noise.
  const AxisCoeffs truth = {0, 5.3e-7, 3e-5, 1.9e-4, 0.4, 1.5e-5, 3.8e-4, 1.2};
  const double noise = 0.05;
  double sum_sq = 0, predicted = 0, at = 0;
  const int kRuns = 40;
  for (int s = 0; s < kRuns; ++s) {
    const AxisData d = changes_of(truth, 30, noise, 100 + s);
    const Refined r = refine_axis(d, truth, RefineOptions{});
    ASSERT_TRUE(r.usable);
    if (s == 0) {
      const Uncertainty u = uncertainty(d, r.coeffs, RefineOptions{});
      predicted = u.angle_sigma_max_arcsec;
      at = u.angle_sigma_at_counts;  // where the predicted 1-sigma is largest
      EXPECT_GT(std::abs(at), 5000.0);  // away from the null, where the angle is pinned
    }
    const double e = rad_to_arcsec(transfer_angle(r.coeffs.data(), at) - transfer_angle(truth.data(), at));
    sum_sq += e * e;
  }
  const double empirical = std::sqrt(sum_sq / kRuns);
  std::printf("angle 1-sigma at N = %.0f: predicted %.4f, scatter of %d fits %.4f arcsec\n", at, predicted, kRuns,
              empirical);
  EXPECT_GT(predicted, 0.5 * empirical);
  EXPECT_LT(predicted, 2.0 * empirical);
}

TEST(Refine, RankDeficientCovarianceFallsBackToThePseudoInverseAndSaysSo) {
  // Both sinusoids at one frequency: their amplitudes and phases trade freely (J^T J singular).
  const AxisCoeffs degenerate = {0, 5.3e-7, 2e-5, 2.5e-4, 0.3, 1e-5, 2.5e-4, 0.3};
  const AxisData d = changes_of(degenerate, 30, 0.05);
  const Uncertainty u = uncertainty(d, degenerate, RefineOptions{});
  EXPECT_TRUE(u.pseudo_inverse);
  EXPECT_NE(u.note.find("rank deficient"), std::string::npos) << u.note;
  for (double s : u.sigma) EXPECT_TRUE(std::isfinite(s));
  // What the data do see stays meaningful: the angle's 1-sigma is of the order of the noise.
  EXPECT_GT(u.angle_sigma_max_arcsec, 0.005);
  EXPECT_LT(u.angle_sigma_max_arcsec, 0.2);
  // A well-posed fit is not flagged.
  const Uncertainty ok = uncertainty(changes_of(kOnGrid, 30, 0.05), kOnGrid, RefineOptions{});
  EXPECT_FALSE(ok.pseudo_inverse) << ok.note;
}

TEST(Refine, DwellGradientIsTheTransferFunctionsDerivativeInScaledUnits) {
  // Central differences of the angle in arcsec over u[1..7] and C1 (as the level), at a few counts.
  const Scaled u0 = to_scaled(kOnGrid);
  for (double n : {-12000.0, -300.0, 0.0, 4711.0, 15000.0}) {
    const Eigen::Matrix<double, 8, 1> g = dwell_gradient(kOnGrid, n);
    for (int p = 0; p < 8; ++p) {
      const int k = p < 7 ? p + 1 : 0;  // u[1..7], then the level u[0]
      const double h = 1e-6 * std::max(1.0, std::abs(u0[k]));
      Scaled up = u0, dn = u0;
      up[k] += h;
      dn[k] -= h;
      const double fd = rad_to_arcsec(transfer_angle(from_scaled(up).data(), n) - transfer_angle(from_scaled(dn).data(), n)) / (2 * h);
      EXPECT_NEAR(g(p), fd, 1e-5 * std::max(1.0, std::abs(fd))) << "n " << n << " parameter " << p;
    }
  }
}

TEST(Refine, RowsFitFindsTheTruthAndAPriorHoldsWhatTheRowsCannotSee) {
  // Absolute rows over the whole field: from a start 1 % off in every sinusoid term, the truth.
  const AxisModel m(kOnGrid);
  std::vector<double> n, y;
  for (int i = 0; i <= 200; ++i) {
    n.push_back(-15000.0 + 150.0 * i);
    y.push_back(m.angle_arcsec(n.back()));
  }
  AxisCoeffs start = kOnGrid;
  for (int k : {2, 3, 5, 6}) start[k] *= 1.01;
  const Refined free = refine_rows(n, y, start, RefineOptions{});
  ASSERT_TRUE(free.usable) << free.brief;
  EXPECT_LT(max_diff_arcsec(free.coeffs, kOnGrid, -15000, 15000), 1e-6);
  // Rows at two counts only: eight coefficients cannot be told apart. A stiff prior about the start
  // on the sinusoids keeps them where it says (the line through the two rows stays free).
  const std::vector<double> n2 = {-1000.0, 1000.0}, y2 = {m.angle_arcsec(-1000.0), m.angle_arcsec(1000.0)};
  ScaledPrior prior;
  prior.u0 = to_scaled(start);
  for (int k : {2, 3, 4, 5, 6, 7}) prior.weight[k] = 1e12;
  const Refined held = refine_rows(n2, y2, start, RefineOptions{}, &prior);
  ASSERT_TRUE(held.usable) << held.brief;
  for (int k : {2, 3, 4, 5, 6, 7}) EXPECT_NEAR(to_scaled(held.coeffs)[k], prior.u0[k], 1e-6 * std::max(1.0, std::abs(prior.u0[k]))) << k;
  for (size_t i = 0; i < n2.size(); ++i) EXPECT_NEAR(AxisModel(held.coeffs).angle_arcsec(n2[i]), y2[i], 1e-6);
}

}  // namespace
}  // namespace fpss::fit
