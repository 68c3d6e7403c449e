// Gauge R&R by ANOVA against an independent computation, and the variance components it recovers.
#include "calib/msa.h"

#include <gtest/gtest.h>

#include <random>
#include <stdexcept>

namespace fpss {
namespace {

// AIAG MSA's ten parts x three appraisers x three trials. The expected figures come from numpy,
// written apart from this code (sums of squares about the part, appraiser and cell means):
//   ssp = o r sum (part mean - grand)^2, sso = p r sum (app mean - grand)^2,
//   sse = sum (y - cell mean)^2, sst = sum (y - grand)^2, sspo = sst - ssp - sso - sse.
GaugeStudy aiag_study() {
  return {{{{0.29, 0.41, 0.64}, {0.08, 0.25, 0.07}, {0.04, -0.11, -0.15}},
           {{-0.56, -0.68, -0.58}, {-0.47, -1.22, -0.68}, {-1.38, -1.13, -0.96}},
           {{1.34, 1.17, 1.27}, {1.19, 0.94, 1.34}, {0.88, 1.09, 0.67}},
           {{0.47, 0.50, 0.64}, {0.01, 1.03, 0.20}, {0.14, 0.20, 0.11}},
           {{-0.80, -0.92, -0.84}, {-0.56, -1.20, -1.28}, {-1.46, -1.07, -1.45}},
           {{0.02, -0.11, -0.21}, {-0.20, 0.22, 0.06}, {-0.29, -0.67, -0.49}},
           {{0.59, 0.75, 0.66}, {0.47, 0.55, 0.83}, {0.02, 0.01, 0.21}},
           {{-0.31, -0.20, -0.17}, {-0.63, 0.08, -0.34}, {-0.46, -0.56, -0.49}},
           {{2.26, 1.99, 2.01}, {1.80, 2.12, 2.19}, {1.77, 1.45, 1.87}},
           {{-1.36, -1.25, -1.31}, {-1.68, -1.62, -1.50}, {-1.49, -1.77, -2.16}}}};
}

TEST(GaugeRr, AnovaOfTheAiagStudyMatchesAnIndependentComputation) {
  const GaugeRr g = gauge_rr(aiag_study(), 4.0);
  EXPECT_NEAR(g.part.ss, 88.36193444444444, 1e-9);
  EXPECT_NEAR(g.appraiser.ss, 3.167262222222222, 1e-9);
  EXPECT_NEAR(g.interaction.ss, 0.3589822222222341, 1e-9);
  EXPECT_NEAR(g.repeatability.ss, 2.7589333333333337, 1e-9);
  EXPECT_NEAR(g.total.ss, 94.64711222222223, 1e-9);
  EXPECT_EQ(g.part.df, 9);
  EXPECT_EQ(g.interaction.df, 18);
  EXPECT_EQ(g.repeatability.df, 60);
  EXPECT_NEAR(g.ev, 0.21443465723203942, 1e-12);
  EXPECT_NEAR(g.av, 0.22830444982675996, 1e-12);
  EXPECT_EQ(g.interaction_sd, 0.0);  // MS_int < MS_e: a negative component, taken as 0
  EXPECT_NEAR(g.grr, 0.31321740697624356, 1e-12);
  EXPECT_NEAR(g.pv, 1.0433945274524374, 1e-12);
  EXPECT_NEAR(g.tv, 1.0893930805501828, 1e-12);
  EXPECT_NEAR(g.grr_percent_tv, 28.751550984522268, 1e-9);
  ASSERT_TRUE(g.grr_percent_tolerance.has_value());
  EXPECT_NEAR(*g.grr_percent_tolerance, 46.98261104643653, 1e-9);
  EXPECT_EQ(g.ndc, 4);
  const auto j = g.to_json();
  EXPECT_EQ(j["ndc"], 4);
  EXPECT_DOUBLE_EQ(j["sd"]["grr"].get<double>(), g.grr);
}

TEST(GaugeRr, RecoversKnownVarianceComponents) {
  // 30 parts (sd 1), 3 appraisers (sd 0.3 each a fixed offset), 5 repeats (sd 0.1): seeded.
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n01(0.0, 1.0);
  GaugeStudy s;
  std::vector<double> offset = {0.3 * n01(rng), 0.3 * n01(rng), 0.3 * n01(rng)};
  for (int i = 0; i < 30; ++i) {
    const double part = n01(rng);
    s.y.emplace_back();
    for (int j = 0; j < 3; ++j) {
      s.y.back().emplace_back();
      for (int k = 0; k < 5; ++k) s.y.back().back().push_back(part + offset[j] + 0.1 * n01(rng));
    }
  }
  const GaugeRr g = gauge_rr(s);
  EXPECT_NEAR(g.ev, 0.1, 0.015);    // 360 degrees of freedom: ~4 % relative scatter
  EXPECT_NEAR(g.pv, 1.0, 0.3);      // 29 parts
  EXPECT_GT(g.av, 0.05);            // three appraisers: the size is poorly known, its presence is not
  EXPECT_FALSE(g.grr_percent_tolerance.has_value());
  // An appraiser who reads 1.0 high shows up as reproducibility, not repeatability.
  GaugeStudy biased = s;
  for (auto& part : biased.y) for (double& v : part[2]) v += 1.0;
  const GaugeRr b = gauge_rr(biased);
  EXPECT_GT(b.av, g.av + 0.3);
  EXPECT_NEAR(b.ev, g.ev, 1e-12);
}

TEST(GaugeRr, UnbalancedOrTooSmallStudiesAreRefused) {
  GaugeStudy s = aiag_study();
  s.y[3][1].pop_back();
  EXPECT_THROW(gauge_rr(s), std::invalid_argument);
  EXPECT_THROW(gauge_rr(GaugeStudy{{{{1.0, 2.0}, {1.0, 2.0}}}}), std::invalid_argument);  // one part
  EXPECT_THROW(gauge_rr(aiag_study(), 0.0), std::invalid_argument);
  GaugeStudy nan = aiag_study();
  nan.y[0][0][0] = std::nan("");
  EXPECT_THROW(gauge_rr(nan), std::invalid_argument);
}

}  // namespace
}  // namespace fpss
