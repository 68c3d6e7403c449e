// What the run's computation steps check: the rows a step may use, a check step's limits.
#pragma once
#include <cstdint>
#include <string>

#include "calib/calibrator.h"
#include "calib/samples.h"
#include "procedures/procedure.h"

namespace fpss {

// The limits `r` breaks, one clause each ("pitch max |residual| 2.300 arcsec > 2.1 arcsec; ..."),
// or "" when none.
std::string check_limits(const ResidualLimits& lim, const ResidualStats& r, const char* axis);
// Residuals a hundred times a limit.
bool absurd(const ResidualLimits& lim, const ResidualStats& r);
// A check step against a calibration: what both axes break ("" when nothing), and when the
// residuals are absurd, the likely cause (the axis mapping or the coefficients).
std::string check_calibration(const CheckStep& step, const CalibrationReport& cal);

}  // namespace fpss
