// How a calibrated unit sits on the gimbal (its null and its roll about the boresight), and one unit relative to another.
#pragma once
#include <vector>

#include "calib/axis_mapping.h"
#include "calib/calibrator.h"
#include "calib/dwells.h"

namespace fpss {

// A unit's pose in the stand frame (arcsec): where its electrical null (zero counts on both axes)
// lies by its calibration, and its roll about the boresight, seen as the cross-talk its dwells
// show between the axes (a roll phi reads alpha = a cos phi - b sin phi, beta = a sin phi + b cos phi).
struct UnitPose {
  double null_pitch_arcsec = 0, null_pitch_sigma_arcsec = 0;
  double null_yaw_arcsec = 0, null_yaw_sigma_arcsec = 0;
  double roll_arcsec = 0, roll_sigma_arcsec = 0;
};

// The null's sigma is the calibration's angle sigma nearest zero (C1, the null condition); the
// roll is a least-squares fit of each axis's residual (its calibrated angle less its reference) on
// the other axis's reference, with the own reference as a regressor so the two never mix.
// Throws DataError when the dwells do not span both axes.
UnitPose unit_pose(const CalibrationReport& cal, const std::vector<Dwell>& dwells, const AxisMapping& axes);

// `other` relative to `first`: differences, the sigmas added in quadrature (their noise is
// independent; the reference they share is common to both fits and cancels to first order, so the
// quadrature sum is an upper bound).
struct RelativePose {
  double boresight_pitch_arcsec = 0, boresight_pitch_sigma_arcsec = 0;
  double boresight_yaw_arcsec = 0, boresight_yaw_sigma_arcsec = 0;
  double roll_arcsec = 0, roll_sigma_arcsec = 0;
};
RelativePose relative_pose(const UnitPose& first, const UnitPose& other);

}  // namespace fpss
