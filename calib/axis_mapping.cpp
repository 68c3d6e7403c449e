#include "calib/axis_mapping.h"

#include <fmt/format.h>

namespace fpss {

std::pair<double, double> AxisMapping::sensor_from_stand(double pitch_arcsec, double yaw_arcsec) const {
  double s[2] = {0, 0};
  s[pitch_axis] = pitch_sign * pitch_arcsec;
  s[yaw_axis] = yaw_sign * yaw_arcsec;
  return {s[alpha], s[beta]};
}

std::pair<double, double> AxisMapping::stand_from_sensor(double alpha_arcsec, double beta_arcsec) const {
  const double s[2] = {alpha_arcsec, beta_arcsec};
  return {pitch_sign * s[pitch_axis], yaw_sign * s[yaw_axis]};
}

std::string AxisMapping::describe() const {
  auto one = [](double sign, SensorAxis a) { return fmt::format("{}{}", sign < 0 ? "-" : "+", a == alpha ? "alpha" : "beta"); };
  return fmt::format("pitch = {}, yaw = {}", one(pitch_sign, pitch_axis), one(yaw_sign, yaw_axis));
}

}  // namespace fpss
