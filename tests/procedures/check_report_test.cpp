// A check step's typed outcome: which limits broke, and the sentence the run prints for it.
#include <gtest/gtest.h>

#include "calib/calibrator.h"
#include "procedures/check_report.h"

namespace fpss {
namespace {

ResidualStats stats(double mean_abs, double sd, double max_abs, size_t points) {
  ResidualStats r;
  r.mean_abs_arcsec = mean_abs;
  r.sd_arcsec = sd;
  r.max_abs_arcsec = max_abs;
  r.points = points;
  return r;
}

CheckStep limits() {
  CheckStep s;
  s.pitch.max_abs_arcsec = 2.1;
  s.pitch.sd_arcsec = 0.5;
  s.yaw.max_abs_arcsec = 2.1;
  s.yaw.min_points = 10;
  return s;
}

TEST(CheckReport, ResidualsWithinTheLimitsPass) {
  const UnitCheck c = check_calibration(limits(), stats(0.1, 0.2, 1.0, 50), stats(0.1, 0.2, 2.0, 50));
  EXPECT_TRUE(c.passed());
  EXPECT_EQ(c.text(), "");
  EXPECT_TRUE(CheckReport{{c}}.passed());
  EXPECT_EQ(CheckReport{{c}}.summary(), "");
}

TEST(CheckReport, EachBrokenLimitIsTypedAndNamed) {
  const UnitCheck c = check_calibration(limits(), stats(0.1, 0.7, 3.76, 50), stats(0.1, 0.2, 1.0, 8));
  ASSERT_EQ(c.breaches.size(), 3u);
  EXPECT_EQ(c.breaches[0].axis, "pitch");
  EXPECT_EQ(c.breaches[0].quantity, LimitBreach::Quantity::sd);
  EXPECT_EQ(c.breaches[1].quantity, LimitBreach::Quantity::max_abs);
  EXPECT_DOUBLE_EQ(c.breaches[1].value, 3.76);
  EXPECT_DOUBLE_EQ(c.breaches[1].limit, 2.1);
  EXPECT_EQ(c.breaches[2].axis, "yaw");
  EXPECT_EQ(c.breaches[2].quantity, LimitBreach::Quantity::points);
  EXPECT_FALSE(c.absurd);
  EXPECT_EQ(c.text(),
            "pitch residual sd 0.700 arcsec > 0.5 arcsec; pitch max |residual| 3.760 arcsec > 2.1 arcsec; "
            "yaw 8 points < 10");
}

TEST(CheckReport, ResidualsAHundredTimesALimitPointAtTheMappingNotTheSensor) {
  const UnitCheck c = check_calibration(limits(), stats(100, 120, 400, 50), stats(0.1, 0.2, 1.0, 50));
  EXPECT_TRUE(c.absurd);
  EXPECT_NE(c.text().find(". Residuals over 100x the limit: the likely cause is the stand file's axis mapping"),
            std::string::npos)
      << c.text();
}

TEST(CheckReport, SeveralUnitsAreNamedAndOnlyTheFailingOnesSpeak) {
  CheckReport r;
  r.units.push_back(check_calibration(limits(), stats(0.1, 0.2, 1.0, 50), stats(0.1, 0.2, 1.0, 50), "SN-A"));
  r.units.push_back(check_calibration(limits(), stats(0.1, 0.2, 2.5, 50), stats(0.1, 0.2, 1.0, 50), "SN-B"));
  EXPECT_FALSE(r.passed());
  EXPECT_EQ(r.summary(), "unit SN-B pitch max |residual| 2.500 arcsec > 2.1 arcsec");
}

TEST(CheckReport, NoCalibrationToCheckFails) {
  CheckReport r;
  r.units.push_back({.unit = "", .calibrated = false});
  EXPECT_FALSE(r.passed());
  EXPECT_EQ(r.summary(), "no calibration to check");
}

}  // namespace
}  // namespace fpss
