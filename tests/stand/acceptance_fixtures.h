// What the acceptance tests share: the shipped limits, and a unit with a bad region.
#pragma once
#include <numbers>

#include "calib/coefficients.h"
#include "calib/units.h"
#include "stand/acceptance/acceptance.h"

namespace fpss::test {

// procedures/acceptance_limits.yaml, read once.
inline const AcceptanceLimits& limits() {
  static const AcceptanceLimits L = load_acceptance_limits(default_limits_path());
  return L;
}

// A sensor whose alpha axis is linear with a fast ripple whose envelope vanishes at the centre
// and grows toward the field's edges: a bad region the 8-coefficient fit cannot follow.
inline CoefficientSet rippled_truth(double amplitude_arcsec) {
  CoefficientSet s = load_published("a-6-fpss1");
  const double a = arcsec_to_rad(amplitude_arcsec);
  const double w1 = 1.6e-3, w2 = w1 + 2 * std::numbers::pi / 30000.0;  // beat period 30000 counts
  s.alpha = {0.0, 0.5326322e-6, a, w1, 0.0, a, w2, std::numbers::pi};
  s.unit = "RIPPLE";
  return s;
}

}  // namespace fpss::test
