// The reference calibration's u carried into a fit's angle sigmas (a type-B contribution).
#pragma once
#include "calib/calibrator.h"
#include "calib/reference_calibration.h"
#include "calib/samples.h"

namespace fpss {

// Every listed angle sigma of both axes grows in quadrature by the reference's u at that angle
// (the other axis anywhere in its calibrated range), angle_sigma_max_arcsec with the worst;
// rep.reference names the file. The coefficients' own sigmas stay the fit's (docs/formats.md).
void add_reference_uncertainty(CalibrationReport& rep, const CalibrationOptions& opts);
// How far the other sensor axis reaches (arcsec) while `sensor_axis` (0 alpha, 1 beta) is
// calibrated: the other's calibrated range, the larger end.
double other_axis_extent_arcsec(const CalibrationReport& rep, int sensor_axis);
// opts.correct_reference: a copy of the table with every row's reference angles corrected;
// otherwise the table itself.
SampleTable with_reference_applied(const SampleTable& t, const CalibrationOptions& opts);

}  // namespace fpss
