// The judge's dwells (the recording's one reduction through the calibration) and the budgets of the accuracy criteria measured on them.
#pragma once
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "calib/uncertainty.h"
#include "stand/acceptance/acceptance.h"

namespace fpss::judged {

struct DwellStats {
  int64_t step = 0;
  PointRole role = PointRole::calibration;
  Phase phase = Phase::null;
  size_t frames = 0;          // the frames the reduction kept
  size_t outliers[2] = {0, 0};  // frames it left out on each axis
  double ref[2] = {0, 0};
  double mean[2] = {0, 0};    // calibrated angle, arcsec
  double sd[2] = {0, 0};      // SD over frames
  double sd_detrended[2] = {0, 0};
  // Standard error of the mean error (angle - reference): the frames' scatter over sqrt(k), the
  // count quantisation (one count, uniform), which averaging over a still dwell does not remove,
  // and the reference's own scatter over its readings. Each is a budget entry (budget()).
  double slope[2] = {0, 0};     // |d angle / d count|, arcsec per count
  double noise[2] = {0, 0};     // slope x sd(counts) / sqrt(k)
  double quant[2] = {0, 0};     // slope / sqrt(12)
  double ref_noise[2] = {0, 0}; // sd(reference readings) / sqrt(their worth in independent readings)
  size_t ref_readings = 0;
  double se[2] = {0, 0};
  double temperature_c = std::numeric_limits<double>::quiet_NaN();  // the sensor's, over the dwell
  // The reference calibration's terms at the dwell (the stand's `reference:`), per sensor axis;
  // empty without one.
  std::vector<BudgetEntry> reference_terms[2];
};

inline double sq(double x) { return x * x; }
inline const char* axis_name(int ax) { return ax == 0 ? "pitch" : "yaw"; }
constexpr double kInfDof = std::numeric_limits<double>::infinity();
// n - 1 degrees of freedom of a figure estimated from n values (at least 1).
inline double dof_of(size_t n) { return n > 1 ? static_cast<double>(n - 1) : 1.0; }

// The judge's dwells are the recording's one reduction (calib/reduction.h), under the rule the
// calibration was made with: the frames it rejects stay out of accuracy and jitter and are judged
// on their own (outlier_frames). Angles are the calibrated transfer function of the dwell's mean
// counts, scatter its slope times the counts' scatter (the counts move by a count or two in a dwell).
std::vector<DwellStats> dwell_stats(const Reduction& reduced, const AcceptanceData& data, const CoefficientSet* cal);

// The error budget of one dwell's mean error: sensor noise (A), quantisation (B), reference noise (A).
std::vector<BudgetEntry> dwell_budget(const DwellStats& d, int ax);

// What calibration.json says of the sensor's temperature on one axis (uncertainties.<axis>.temperature):
// the temperature it holds at and its fitted sensitivity, u the sensitivity's estimate and sigma
// combined (an effect the calibration did not correct, docs/calibration.md).
struct TemperatureSensitivity {
  double reference_c = 0, u_arcsec_per_c = 0, dof = std::numeric_limits<double>::infinity();
};
std::optional<TemperatureSensitivity> temperature_sensitivity(const CoefficientSet* cal, int ax);

// The temperature's entry of an angle error measured at dwells whose temperatures lie `dt_c` (RMS)
// from the calibration's: none when the recording or the calibration has no temperature.
void add_temperature(std::vector<BudgetEntry>& b, const std::optional<TemperatureSensitivity>& t, double dt_c,
                     double sensitivity, const char* what);
// A dwell's temperature less the calibration's (NaN: either is unknown).
double temperature_offset(const DwellStats& d, const std::optional<TemperatureSensitivity>& t);
// The RMS of that over the dwells that have a temperature (NaN: none has).
double rms_temperature_offset(const std::vector<const DwellStats*>& dwells, const std::optional<TemperatureSensitivity>& t);

// The reference's terms (the stand's `reference:`) at the dwell of the set where its u is largest:
// what the unit's true errors have (its calibration inherits the reference's error) and its measured
// ones, taken against the same reference, lack.
void add_reference_terms(std::vector<BudgetEntry>& b, const AcceptanceData& data,
                         const std::vector<const DwellStats*>& dwells, int ax);
// The 3-sigma figure's: the dwell means' noise that inflates an RMS, and the reference's u over the points.
void add_rms_terms(std::vector<BudgetEntry>& b, const AcceptanceData& data,
                   const std::vector<const DwellStats*>& points, int ax, double rms);
// A worst-of-n figure's: the noise's lift of a maximum (seeded redraws).
void add_selection_lift(std::vector<BudgetEntry>& b, const std::vector<const DwellStats*>& dwells, int ax);

}  // namespace fpss::judged
