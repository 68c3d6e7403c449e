// How the sensor is mounted on the gimbal: each stand axis seen as a signed sensor axis (one type for the stand and the emulated bench).
#pragma once
#include <string>
#include <utility>

namespace fpss {

// How the sensor is mounted on the gimbal: each stand axis as a signed sensor axis.
// Default pitch = +alpha, yaw = +beta; the paper's Table 2 needs pitch = +beta, yaw = -alpha.
struct AxisMapping {
  enum SensorAxis { alpha = 0, beta = 1 };
  SensorAxis pitch_axis = alpha, yaw_axis = beta;
  double pitch_sign = 1, yaw_sign = 1;

  // Reference angles of the Sun in the sensor frame (what alpha and beta measure) from gimbal
  // angles: the samples contract's ref_pitch_arcsec (alpha) and ref_yaw_arcsec (beta).
  std::pair<double, double> sensor_from_stand(double pitch_arcsec, double yaw_arcsec) const;
  std::pair<double, double> stand_from_sensor(double alpha_arcsec, double beta_arcsec) const;
  std::string describe() const;  // "pitch = +beta, yaw = -alpha"
  bool valid() const { return pitch_axis != yaw_axis && (pitch_sign == 1 || pitch_sign == -1) &&
                              (yaw_sign == 1 || yaw_sign == -1); }
};

}  // namespace fpss
