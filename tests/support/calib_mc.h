// Monte Carlo of the calibrator on recordings from the independent Python generator
// (tests/gen/grid_gen.py): errors against the truth, coverage of the reported 1-sigma, and the
// Cramer-Rao bound of the design, computed here from the design alone (not from the calibrator).
// Shared by the statistics benchmark and its small ctest.
#pragma once
#include <Eigen/Dense>

#include <array>
#include <cmath>
#include <cstdlib>
#include <numbers>
#include <string>
#include <vector>

#include "calib/calibrator.h"
#include "calib/coefficients.h"
#include "calib/units.h"
#include "tests/support/test_support.h"

namespace fpss::test::mc {

// A benchmark's size from the environment (FPSS_MC_RECORDINGS, ...), else the fallback.
inline int env_int(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v && *v ? std::atoi(v) : fallback;
}

// The grid the generator records: offsets +-step .. +-extent along pitch, then yaw, each between
// two null dwells.
struct Design {
  double extent_deg = 0.45, step_deg = 0.03;
  int samples_per_dwell = 5;
  double count_noise_counts = 0.3, ref_noise_arcsec = 0.05;
  double outlier_rate = 0;  // fraction of frames whose alpha count is off by 20..200 counts
  int frames_per_reading = 1;  // consecutive frames that share one encoder reading
  fs::path gimbal_errors;      // a reference calibration file whose terms are drawn per recording ("": none)
  // A sensor temperature 20 + A sin(...) C in every frame, moving its line of sight by K (T - 20)
  // arcsec (A = 0: no temperature column).
  double temperature_amplitude_c = 0, temperature_arcsec_per_c = 0;
  // After the grid, verification dwells at the midpoints between its offsets (an acceptance's).
  bool verification = false;

  // The (pitch, yaw) true angles (arcsec) of every dwell in recording order, step k + 1 at index
  // k: the grid's, then with `verification` the midpoints' (grid_gen.py plan()).
  std::vector<std::array<double, 2>> step_angles_arcsec() const {
    std::vector<std::array<double, 2>> out{{0.0, 0.0}};
    const int k = static_cast<int>(std::floor(extent_deg / step_deg + 1e-9));
    for (double shift : verification ? std::vector<double>{0.0, 0.5} : std::vector<double>{0.0}) {
      for (int axis = 0; axis < 2; ++axis) {
        for (int i = 1; i <= k; ++i) {
          for (double sgn : {1.0, -1.0}) {
            const double o = sgn * (i - shift) * step_deg * kArcsecPerDeg;
            out.push_back(axis == 0 ? std::array<double, 2>{o, 0.0} : std::array<double, 2>{0.0, o});
            out.push_back({0.0, 0.0});
          }
        }
      }
    }
    return out;
  }
  // How many of those steps are the grid's (the rest verify).
  size_t grid_steps() const { return 1 + 8 * static_cast<size_t>(std::floor(extent_deg / step_deg + 1e-9)); }

  // The angle (arcsec) of every dwell along one axis, in recording order (the other axis's offsets
  // are dwells at 0 along this one).
  std::vector<double> dwell_angles_arcsec(bool pitch) const {
    std::vector<double> out{0.0};
    const int k = static_cast<int>(std::floor(extent_deg / step_deg + 1e-9));
    for (int axis = 0; axis < 2; ++axis) {
      for (int i = 1; i <= k; ++i) {
        for (double sgn : {1.0, -1.0}) {
          out.push_back((axis == 0) == pitch ? sgn * i * step_deg * kArcsecPerDeg : 0.0);
          out.push_back(0.0);
        }
      }
    }
    return out;
  }
};

// Runs the generator (posix_spawn of /usr/bin/python3 with an argv); returns the files written.
inline std::vector<fs::path> generate(const fs::path& truth, const fs::path& dir, int recordings, uint64_t seed,
                                      const Design& d) {
  fs::create_directories(dir);
  std::vector<std::string> argv{
      "/usr/bin/python3", (source_dir() / "tests/gen/grid_gen.py").string(), "--truth", truth.string(), "--out-dir",
      dir.string(), "--recordings", std::to_string(recordings), "--seed", std::to_string(seed),
      "--samples-per-dwell", std::to_string(d.samples_per_dwell), "--count-noise-counts",
      std::to_string(d.count_noise_counts), "--ref-noise-arcsec", std::to_string(d.ref_noise_arcsec),
      "--extent-deg", std::to_string(d.extent_deg), "--step-deg", std::to_string(d.step_deg), "--outlier-rate",
      std::to_string(d.outlier_rate), "--frames-per-reading", std::to_string(d.frames_per_reading),
      "--gimbal-errors", d.gimbal_errors.string(), "--temperature-amplitude-c",
      std::to_string(d.temperature_amplitude_c), "--temperature-arcsec-per-c", std::to_string(d.temperature_arcsec_per_c)};
  if (d.verification) argv.push_back("--verification");
  const CommandResult r = run_command(argv, dir, "grid_gen");
  if (r.code != 0) throw std::runtime_error("grid_gen.py failed: " + r.err);
  std::vector<fs::path> files;
  std::istringstream lines(r.out);
  for (std::string l; std::getline(lines, l);) {
    if (!l.empty()) files.emplace_back(l);
  }
  return files;
}

// Fisher information of one whole count round(n + e), e ~ N(0, s^2), about n: sum_k p_k'^2 / p_k.
inline double rounded_fisher(double n, double s) {
  const double base = std::floor(n);
  const double w = std::ceil(10 * s) + 2;
  auto pdf = [](double z) { return std::exp(-0.5 * z * z) / std::sqrt(2 * std::numbers::pi); };
  auto cdf = [](double z) { return 0.5 * std::erfc(-z / std::numbers::sqrt2); };
  double info = 0;
  for (double k = base - w; k <= base + w; k += 1.0) {
    const double p = cdf((k + 0.5 - n) / s) - cdf((k - 0.5 - n) / s);
    const double dp = (pdf((k - 0.5 - n) / s) - pdf((k + 0.5 - n) / s)) / s;
    if (p > 1e-300) info += dp * dp / p;
  }
  return info;
}

// d angle(n) / d(u1..u7, level), arcsec per scaled unit: angle = level + u1 x + u2 sin(u3 x + u4)
// + u5 sin(u6 x + u7), x = n / 16384 (the calibrator's scaling; any would give the same sigma).
inline Eigen::Matrix<double, 8, 1> design_gradient(const AxisCoeffs& c, double n) {
  const double x = n / 16384.0;
  const double u2 = c[2] * kArcsecPerRad, u3 = c[3] * 16384.0, u5 = c[5] * kArcsecPerRad, u6 = c[6] * 16384.0;
  const double a = u3 * x + c[4], b = u6 * x + c[7];
  Eigen::Matrix<double, 8, 1> g;
  g << x, std::sin(a), u2 * std::cos(a) * x, u2 * std::cos(a), std::sin(b), u5 * std::cos(b) * x,
      u5 * std::cos(b), 1.0;
  return g;
}

// The Cramer-Rao bound of the design at the truth for one axis: per dwell the reference mean
// (variance ref^2 / m) and the count (Fisher information m I(n) of m rounded Gaussian counts), one
// reference level (the changes lose it; the null condition puts C1 at it). Returns the 1-sigma of
// the transfer function at each count of `counts` (C1 included).
inline std::vector<double> crb_sigma_arcsec(const AxisCoeffs& truth, const Design& d, bool pitch,
                                            const std::vector<double>& counts) {
  const AxisModel model(truth);
  const auto angles = d.dwell_angles_arcsec(pitch);
  Eigen::MatrixXd j(static_cast<Eigen::Index>(angles.size()), 8);
  const double m = d.samples_per_dwell;
  for (size_t k = 0; k < angles.size(); ++k) {
    const double n = model.counts_for_angle(arcsec_to_rad(angles[k]));
    const double slope = rad_to_arcsec(model.slope_rad_per_count(n));
    const double var = d.ref_noise_arcsec * d.ref_noise_arcsec / m +
                       slope * slope / (m * rounded_fisher(n, d.count_noise_counts));
    j.row(static_cast<Eigen::Index>(k)) = design_gradient(truth, n).transpose() / std::sqrt(var);
  }
  const Eigen::MatrixXd fisher = j.transpose() * j;
  const Eigen::MatrixXd cov = fisher.completeOrthogonalDecomposition().pseudoInverse();
  std::vector<double> out;
  for (double n : counts) {
    const auto g = design_gradient(truth, n);
    out.push_back(std::sqrt(std::max(0.0, g.dot(cov * g))));
  }
  return out;
}

// Counts over the calibrated range (the truth's counts at -extent .. +extent), evenly.
inline std::vector<double> range_counts(const AxisCoeffs& truth, const Design& d, int steps = 200) {
  const AxisModel model(truth);
  const double lo = model.counts_for_angle(arcsec_to_rad(-d.extent_deg * kArcsecPerDeg));
  const double hi = model.counts_for_angle(arcsec_to_rad(d.extent_deg * kArcsecPerDeg));
  std::vector<double> out;
  for (int i = 0; i <= steps; ++i) out.push_back(lo + (hi - lo) * i / steps);
  return out;
}

// One axis's tallies over many recordings.
struct AxisTally {
  double sum_sq_err = 0;  // over recordings and the range's counts, arcsec^2
  size_t err_points = 0;
  double max_abs_err = 0;
  size_t covered1 = 0, covered2 = 0, angles = 0;  // listed angles with |error| <= 1, 2 sigma
  double sum_z2 = 0;  // sum of (error / sigma)^2 at the listed angles

  void add(const AxisFit& fit, const AxisCoeffs& truth, const std::vector<double>& counts) {
    const AxisModel t(truth);
    for (double n : counts) {
      const double e = rad_to_arcsec(transfer_angle(fit.coeffs.data(), n) - t.angle_rad(n));
      sum_sq_err += e * e;
      ++err_points;
      max_abs_err = std::max(max_abs_err, std::abs(e));
    }
    for (const auto& [angle, sigma] : fit.angle_sigma_arcsec) {
      if (!std::isfinite(sigma)) continue;
      const double n = t.counts_for_angle(arcsec_to_rad(angle));
      const double e = rad_to_arcsec(transfer_angle(fit.coeffs.data(), n)) - angle;
      covered1 += std::abs(e) <= sigma;
      covered2 += std::abs(e) <= 2 * sigma;
      sum_z2 += (e / sigma) * (e / sigma);
      ++angles;
    }
  }
  double rms_err() const { return err_points ? std::sqrt(sum_sq_err / static_cast<double>(err_points)) : NAN; }
  double coverage1() const { return angles ? static_cast<double>(covered1) / static_cast<double>(angles) : NAN; }
  double coverage2() const { return angles ? static_cast<double>(covered2) / static_cast<double>(angles) : NAN; }
};

inline double rms_of(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return v.empty() ? NAN : std::sqrt(s / static_cast<double>(v.size()));
}

}  // namespace fpss::test::mc
