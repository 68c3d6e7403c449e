// A check step's outcome as a type: each limit a unit's residuals broke, and the sentence a run prints for it.
#pragma once
#include <string>
#include <vector>

#include "procedures/procedure.h"

namespace fpss {

struct ResidualStats;  // calib/calibrator.h: kept out of the engine's headers (Eigen)

// One limit of a check step that one axis's residuals broke.
struct LimitBreach {
  enum class Quantity { mean_abs, sd, max_abs, points };
  std::string axis;  // "pitch" or "yaw", as the stand reports them
  Quantity quantity = Quantity::max_abs;
  double value = 0;  // arcsec; a count of points for Quantity::points
  double limit = 0;
  std::string text() const;  // "pitch max |residual| 2.300 arcsec > 2.1 arcsec"
};

// One unit's outcome of a check step.
struct UnitCheck {
  std::string unit;         // its serial in a run of several units; "" in a run of one
  bool calibrated = true;   // false: there was no calibration to check (the check fails)
  std::vector<LimitBreach> breaches{};
  // Residuals over 100 times a limit: not a worn sensor, but the stand file's axis mapping or the
  // coefficients the fit started from.
  bool absurd = false;
  bool passed() const { return calibrated && breaches.empty(); }
  std::string text() const;  // what broke, "" when nothing did
};

// What a check step found, unit by unit (the engine stops the run with StopCause::check_failed when
// it did not pass; investigate and diagnose read the same report).
struct CheckReport {
  std::vector<UnitCheck> units{};
  bool passed() const;
  std::string summary() const;  // "" when passed, else what broke ("unit SN ..." for each of several)
};

// One unit's calibration residuals against a check step's limits.
UnitCheck check_calibration(const CheckStep& step, const ResidualStats& pitch, const ResidualStats& yaw,
                            std::string unit = "");

}  // namespace fpss
