// The transfer function (paper eq. 1, 2), its slope and inverse, and the paper's Table 2.
#include "calib/transfer_function.h"

#include <gtest/gtest.h>

#include <cmath>

#include "calib/coefficients.h"
#include "calib/units.h"

namespace fpss {
namespace {

const AxisCoeffs kPrelaunch = {0.1090831e-3, 0.5326322e-6, 0.1335975e-4, 0.1917476e-3,
                               0.29628831e1, 0.1745964e-4, 0.3834951e-3, 0.8659915};

TEST(TransferFunction, IsEquationOne) {
  for (double n : {-16000.0, -123.5, 0.0, 777.0, 15000.0}) {
    const auto& c = kPrelaunch;
    const double expect = c[0] + c[1] * n + c[2] * std::sin(c[3] * n + c[4]) + c[5] * std::sin(c[6] * n + c[7]);
    EXPECT_DOUBLE_EQ(transfer_angle(c.data(), n), expect);
    EXPECT_DOUBLE_EQ(AxisModel(c).angle_arcsec(n), rad_to_arcsec(expect));
  }
}

TEST(TransferFunction, SlopeIsTheDerivative) {
  const AxisModel m(kPrelaunch);
  for (double n : {-15000.0, -3000.0, 0.0, 4242.0, 16000.0}) {
    const double h = 0.5;
    const double numeric = (m.angle_rad(n + h) - m.angle_rad(n - h)) / (2 * h);
    EXPECT_NEAR(m.slope_rad_per_count(n), numeric, 1e-9 * std::abs(numeric));
  }
}

TEST(TransferFunction, InverseRoundTripsOverTheField) {
  const AxisModel m(kPrelaunch);
  for (double n = -16000; n <= 16000; n += 1234.5) {
    EXPECT_NEAR(m.counts_for_angle(m.angle_rad(n), -16384, 16384), n, 1e-6);
  }
}

TEST(TransferFunction, InverseNamesAnAngleOutOfRange) {
  const AxisModel m(kPrelaunch);
  try {
    m.counts_for_angle(arcsec_to_rad(5000.0), -16384, 16384);
    FAIL() << "expected out_of_range";
  } catch (const std::out_of_range& e) {
    EXPECT_NE(std::string(e.what()).find("5000.000 arcsec"), std::string::npos) << e.what();
  }
}

TEST(TransferFunction, InverseRefusesANonMonotonicFunction) {
  // A sinusoid whose slope C3*C4 = 3e-6 rad/count beats C2 = 5e-7: the slope changes sign.
  const AxisModel m({0.0, 5e-7, 1e-2, 3e-4, 0.0, 0.0, 1e-4, 0.0});
  EXPECT_THROW(m.check_monotonic(-16384, 16384), NotMonotonicError);
  try {
    m.counts_for_angle(0.001, -16384, 16384);
    FAIL() << "expected NotMonotonicError";
  } catch (const NotMonotonicError& e) {
    EXPECT_NE(std::string(e.what()).find("not monotonic"), std::string::npos);
  }
  // The published sets are monotonic over the whole 15-bit range.
  for (const auto& name : published_names()) {
    const auto s = load_published(name);
    EXPECT_NO_THROW(s.alpha_model().check_monotonic()) << name;
    EXPECT_NO_THROW(s.beta_model().check_monotonic()) << name;
  }
}

TEST(TransferFunction, ServesOtherScalarTypes) {
  // The same template serves other number types (Ceres jets in the fit): long double here.
  long double c[8];
  for (int i = 0; i < 8; ++i) c[i] = kPrelaunch[i];
  EXPECT_NEAR(static_cast<double>(transfer_angle(c, 1000.0L)), transfer_angle(kPrelaunch.data(), 1000.0), 1e-15);
}

// Table 2 of the paper from Table A-7, FPSS1, with pitch = beta(N) and yaw = -alpha(N).
TEST(TransferFunction, PaperTableTwoFromTableA7) {
  const CoefficientSet a7 = load_published("a-7-fpss1");
  const AxisModel alpha = a7.alpha_model(), beta = a7.beta_model();
  const double south = beta.angle_arcsec(10394.5);
  const double north = beta.angle_arcsec(-6517.0);
  const double east_alpha = alpha.angle_arcsec(-7363.5);
  const double west_alpha = alpha.angle_arcsec(9812.0);
  EXPECT_NEAR(south, 944.4, 0.1);
  EXPECT_NEAR(north, -949.8, 0.1);
  EXPECT_NEAR(east_alpha, -957.7, 0.1);
  EXPECT_NEAR(west_alpha, 944.9, 0.1);
  const double yaw_east = -east_alpha, yaw_west = -west_alpha;
  EXPECT_NEAR(south - north, 1894.2, 0.1);       // N-S diameter
  EXPECT_NEAR(yaw_east - yaw_west, 1902.6, 0.1);  // E-W diameter
}

}  // namespace
}  // namespace fpss
