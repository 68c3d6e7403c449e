#include "calib/unit_alignment.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>

#include "base/errors.h"
#include "calib/transfer_function.h"
#include "calib/units.h"

namespace fpss {

namespace {

// The angle sigma listed nearest `angle_arcsec`.
double sigma_near(const AxisFit& f, double angle_arcsec) {
  double best = std::numeric_limits<double>::infinity(), sigma = f.angle_sigma_max_arcsec;
  for (const auto& [angle, s] : f.angle_sigma_arcsec) {
    if (std::abs(angle - angle_arcsec) < best && std::isfinite(s)) {
      best = std::abs(angle - angle_arcsec);
      sigma = s;
    }
  }
  return sigma;
}

struct Slope {
  double value = 0, sigma = std::numeric_limits<double>::infinity();
};

// r = c + s * cross + t * own, by least squares: s and its standard error.
Slope cross_slope(const std::vector<double>& r, const std::vector<double>& cross, const std::vector<double>& own) {
  const Eigen::Index n = static_cast<Eigen::Index>(r.size());
  if (n < 4) return {};
  Eigen::MatrixXd X(n, 3);
  Eigen::VectorXd y(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    X(i, 0) = 1;
    X(i, 1) = cross[static_cast<size_t>(i)];
    X(i, 2) = own[static_cast<size_t>(i)];
    y(i) = r[static_cast<size_t>(i)];
  }
  const Eigen::Matrix3d xtx = X.transpose() * X;
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(xtx);
  if (lu.rank() < 3) return {};
  const Eigen::Vector3d b = lu.solve(X.transpose() * y);
  const double s2 = (y - X * b).squaredNorm() / static_cast<double>(n - 3);
  const Eigen::Matrix3d cov = lu.inverse() * s2;
  return {b(1), std::sqrt(std::max(0.0, cov(1, 1)))};
}

}  // namespace

UnitPose unit_pose(const CalibrationReport& cal, const std::vector<Dwell>& dwells, const AxisMapping& axes) {
  const AxisModel alpha(cal.pitch.coeffs), beta(cal.yaw.coeffs);
  UnitPose p;
  // The null in the sensor frame, then on the gimbal's axes.
  const double a0 = alpha.angle_arcsec(0), b0 = beta.angle_arcsec(0);
  const auto [pitch0, yaw0] = axes.stand_from_sensor(a0, b0);
  p.null_pitch_arcsec = pitch0;
  p.null_yaw_arcsec = yaw0;
  const double sa = sigma_near(cal.pitch, a0), sb = sigma_near(cal.yaw, b0);
  // Which sensor axis a stand axis reads.
  p.null_pitch_sigma_arcsec = axes.pitch_axis == AxisMapping::alpha ? sa : sb;
  p.null_yaw_sigma_arcsec = axes.pitch_axis == AxisMapping::alpha ? sb : sa;

  std::vector<double> ra, rb, ref_a, ref_b;
  for (const Dwell& d : dwells) {
    if (d.samples == 0) continue;
    ra.push_back(alpha.angle_arcsec(d.counts_alpha) - d.ref_pitch_arcsec);  // the samples' ref_pitch is alpha's
    rb.push_back(beta.angle_arcsec(d.counts_beta) - d.ref_yaw_arcsec);
    ref_a.push_back(d.ref_pitch_arcsec);
    ref_b.push_back(d.ref_yaw_arcsec);
  }
  const Slope s_a = cross_slope(ra, ref_b, ref_a), s_b = cross_slope(rb, ref_a, ref_b);
  if (!std::isfinite(s_a.sigma) || !std::isfinite(s_b.sigma)) {
    throw DataError("unit pose: the dwells do not span both axes (no roll can be told)");
  }
  // alpha's residual goes as -sin(phi) b, beta's as +sin(phi) a: the weighted mean of both.
  const double wa = 1 / (s_a.sigma * s_a.sigma), wb = 1 / (s_b.sigma * s_b.sigma);
  const double sin_phi = (-s_a.value * wa + s_b.value * wb) / (wa + wb);
  const double sigma = std::sqrt(1 / (wa + wb));
  // A mirrored mapping (one axis's sign flipped, or the axes swapped) turns the sense of a roll.
  const double pa = axes.pitch_axis == AxisMapping::alpha ? 1.0 : -1.0;
  const double handedness = pa * axes.pitch_sign * axes.yaw_sign;
  p.roll_arcsec = handedness * rad_to_arcsec(std::asin(std::clamp(sin_phi, -1.0, 1.0)));
  p.roll_sigma_arcsec = rad_to_arcsec(sigma);
  return p;
}

RelativePose relative_pose(const UnitPose& first, const UnitPose& other) {
  auto rss = [](double a, double b) { return std::sqrt(a * a + b * b); };
  return {other.null_pitch_arcsec - first.null_pitch_arcsec, rss(first.null_pitch_sigma_arcsec, other.null_pitch_sigma_arcsec),
          other.null_yaw_arcsec - first.null_yaw_arcsec,     rss(first.null_yaw_sigma_arcsec, other.null_yaw_sigma_arcsec),
          other.roll_arcsec - first.roll_arcsec,             rss(first.roll_sigma_arcsec, other.roll_sigma_arcsec)};
}

}  // namespace fpss
