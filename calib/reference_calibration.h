// The reference's own calibration (the gimbal's certificate): its error model, its inverse and its type-B uncertainty.
#pragma once
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/axis_mapping.h"
#include "calib/uncertainty.h"

namespace fpss {

// One term of a certificate: its value and its standard uncertainty (same unit).
struct CertifiedValue {
  double value = 0, u = 0;
};

// One harmonic of an encoder's cyclic error: amplitude * sin(harmonic * angle + phase), angle the
// axis's true angle in radians (`harmonic` cycles per revolution of the axis).
struct CyclicTerm {
  int harmonic = 1;
  CertifiedValue amplitude_arcsec, phase_rad;
};

// One gimbal axis's errors: its encoder's reading minus the true angle (docs/formats.md,
// "Reference calibration file").
struct ReferenceAxis {
  CertifiedValue scale_factor_ppm;         // reading gains ppm 1e-6 times the true angle
  CertifiedValue nonorthogonality_arcsec;  // reading gains sin(this) times the OTHER axis's true angle
  CertifiedValue zero_arcsec;              // reading gains this
  std::vector<CyclicTerm> cyclic;
};

struct ReferenceCalibration {
  std::string file;    // the path it was read from, as given
  std::string sha256;  // of the file's bytes
  std::string certificate, date, lab;
  ReferenceAxis pitch, yaw;

  // The encoders' readings of the true gimbal angles (stand frame, arcsec): the error model.
  std::pair<double, double> reading_from_true(double pitch_arcsec, double yaw_arcsec) const;
  // Its inverse: the true angles that read (pitch, yaw); Newton's method to 1e-9 arcsec.
  std::pair<double, double> true_from_reading(double pitch_arcsec, double yaw_arcsec) const;
  // The standard uncertainty (arcsec) of each corrected (true) angle at these true angles, from
  // every term's u to first order, terms independent (docs/formats.md).
  std::pair<double, double> u_true_arcsec(double pitch_arcsec, double yaw_arcsec) const;
  // {file, sha256, certificate, date, lab}: what calibration.json, run.json and the certificate name.
  nlohmann::json identity() const;
};

// A row's reference angles (sensor frame, the samples contract's ref_pitch/ref_yaw) made true:
// to the gimbal's axes through `mount`, true_from_reading, and back.
void correct_reference_angles(const ReferenceCalibration& r, const AxisMapping& mount, double& ref_pitch_arcsec,
                              double& ref_yaw_arcsec);
// The reference's terms' contributions (type B, arcsec) to the sensor-frame angle `sensor_axis`
// (0 alpha, 1 beta) at `angle`, the other sensor axis where their sum is worst within
// +-other_extent (its two ends and zero): one entry per term, "reference calibration: pitch zero".
std::vector<BudgetEntry> reference_budget(const ReferenceCalibration& r, const AxisMapping& mount, int sensor_axis,
                                          double angle_arcsec, double other_extent_arcsec);
// The same at a known position of the other sensor axis (`other_arcsec`): a measured point's.
std::vector<BudgetEntry> reference_terms_at(const ReferenceCalibration& r, const AxisMapping& mount, int sensor_axis,
                                            double angle_arcsec, double other_arcsec);
// That worst position of the other sensor axis (arcsec).
double reference_worst_other_arcsec(const ReferenceCalibration& r, const AxisMapping& mount, int sensor_axis,
                                    double angle_arcsec, double other_extent_arcsec);
// The reading minus the true angle (arcsec) of the gimbal axis that sensor axis `sensor_axis` sees,
// at the sensor-frame angles (angle on that axis, other on the other).
double reference_error_arcsec(const ReferenceCalibration& r, const AxisMapping& mount, int sensor_axis,
                              double angle_arcsec, double other_arcsec);
// Their root sum of squares: the reference's u (arcsec) of that angle.
double reference_u_arcsec(const ReferenceCalibration& r, const AxisMapping& mount, int sensor_axis, double angle_arcsec,
                          double other_extent_arcsec);

// The limits a file's terms must keep (docs/formats.md, Limits).
inline constexpr double kMaxReferenceScalePpm = 10000;
inline constexpr double kMaxReferenceAngleArcsec = 3600;  // nonorthogonality, zero, cyclic amplitude
inline constexpr int kMaxReferenceHarmonic = 64;
inline constexpr size_t kMaxReferenceCyclicTerms = 16;

// Strict: unknown or missing keys, wrong types, non-finite or out-of-range values -> InputError
// "<origin>: key \"pitch.scale_factor_ppm.u\": ...". `sha256` is left empty.
ReferenceCalibration parse_reference_calibration(const nlohmann::json& j, const std::string& origin);
// read_json_file, parse, and the sha256 of the file's bytes.
ReferenceCalibration load_reference_calibration(const std::filesystem::path& path);

}  // namespace fpss
