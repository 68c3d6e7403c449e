// The Monte Carlo check of the calibration's GUM budget (JCGM 101): it agrees where the GUM holds and says so where it does not.
#include "calib/monte_carlo.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "fixtures/recording.h"

namespace fpss {
namespace {

CalibrationReport calibrated(CalibrationOptions& o) {
  BenchConfig cfg = default_bench_config();
  cfg.truth = load_published("a-6-fpss1");
  cfg.seed = 11;
  o.threads = 1;
  return calibrate(simulate_null_offset(cfg, {}), o);
}

nlohmann::json certified(double v, double u) { return {{"value", v}, {"u", u}}; }

nlohmann::json reference_axis(nlohmann::json cyclic) {
  return {{"scale_factor_ppm", certified(0, 20)}, {"nonorthogonality_arcsec", certified(0, 2)},
          {"zero_arcsec", certified(0, 1)}, {"cyclic", cyclic}};
}

TEST(MonteCarlo, AgreesWithTheBudgetWhereTheGumHolds) {
  CalibrationOptions o;
  o.reference = parse_reference_calibration({{"certificate", "C"}, {"date", "2026-01-01"}, {"lab", "l"},
                                             {"pitch", reference_axis(nlohmann::json::array())},
                                             {"yaw", reference_axis(nlohmann::json::array())}},
                                            "ref.json");
  const CalibrationReport rep = calibrated(o);
  const MonteCarloCheck mc = monte_carlo_check(rep, o, 400000, 7);
  ASSERT_EQ(mc.axes.size(), 2u);
  for (const MonteCarloAxis& a : mc.axes) {
    EXPECT_TRUE(a.gum_validated) << a.axis << " d_low " << a.d_low_arcsec << " d_high " << a.d_high_arcsec
                                 << " tolerance " << a.tolerance_arcsec;
    EXPECT_NEAR(a.u_arcsec, a.gum_u_arcsec, 0.01 * a.gum_u_arcsec);
    EXPECT_NEAR(a.mean_arcsec, 0.0, 0.01 * a.gum_u_arcsec);
    EXPECT_LT(a.low_arcsec, 0.0);
    EXPECT_GT(a.high_arcsec, 0.0);
  }
  // The same seed, the same draws.
  EXPECT_EQ(monte_carlo_check(rep, o, 1000, 3).to_json(), monte_carlo_check(rep, o, 1000, 3).to_json());
}

TEST(MonteCarlo, FindsWhereTheLinearisedBudgetFails) {
  // A 5 arcsec cyclic error whose phase is known to 1.5 rad only: to first order its u is
  // 5 x 1.5 |cos(phase)| = 7.5 arcsec near zero phase, while 5 sin(phase + d) spreads by 3.5.
  CalibrationOptions o;
  const nlohmann::json cyclic =
      nlohmann::json::array({{{"harmonic", 1}, {"amplitude_arcsec", certified(5, 0.01)}, {"phase_rad", certified(0, 1.5)}}});
  o.reference = parse_reference_calibration({{"certificate", "C"}, {"date", "2026-01-01"}, {"lab", "l"},
                                             {"pitch", reference_axis(cyclic)},
                                             {"yaw", reference_axis(nlohmann::json::array())}},
                                            "ref.json");
  const CalibrationReport rep = calibrated(o);
  const MonteCarloCheck mc = monte_carlo_check(rep, o, 100000, 7);
  ASSERT_EQ(mc.axes.size(), 2u);
  EXPECT_EQ(mc.axes[0].axis, "pitch");
  EXPECT_FALSE(mc.axes[0].gum_validated);
  EXPECT_LT(mc.axes[0].u_arcsec, 0.7 * mc.axes[0].gum_u_arcsec);
  EXPECT_TRUE(mc.axes[1].gum_validated);
  EXPECT_NE(monte_carlo_text(mc).find("NOT validated"), std::string::npos);
  // Which way U errs, and what that means: the drawn interval is narrower, so U is conservative.
  EXPECT_NE(monte_carlo_text(mc).find("its +-U is wider than the Monte Carlo 95 % interval"), std::string::npos);
  EXPECT_NE(monte_carlo_text(mc).find("U overstates this angle's uncertainty (safe but conservative)"), std::string::npos);
  EXPECT_NE(monte_carlo_text(mc).find("the GUM budget is validated: its U holds as stated"), std::string::npos);  // yaw
}

TEST(MonteCarlo, TrialsOutOfRangeAreRefused) {
  CalibrationOptions o;
  const CalibrationReport rep = calibrated(o);
  EXPECT_THROW(monte_carlo_check(rep, o, 99), std::invalid_argument);
  EXPECT_THROW(monte_carlo_check(rep, o, 10'000'001), std::invalid_argument);
}

}  // namespace
}  // namespace fpss
