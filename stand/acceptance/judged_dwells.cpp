#include "stand/acceptance/judged_dwells.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "calib/units.h"

namespace fpss::judged {

// The judge's dwells are the recording's one reduction (calib/reduction.h), under the rule the
// calibration was made with: the frames it rejects stay out of accuracy and jitter and are judged
// on their own (outlier_frames). Angles are the calibrated transfer function of the dwell's mean
// counts, scatter its slope times the counts' scatter (the counts move by a count or two in a dwell).
std::vector<DwellStats> dwell_stats(const Reduction& reduced, const AcceptanceData& data, const CoefficientSet* cal) {
  std::vector<DwellStats> out;
  for (const Dwell& w : reduced.dwells) {
    DwellStats d;
    d.step = w.step;
    const auto role = data.roles.find(d.step);
    d.role = role == data.roles.end() ? PointRole::calibration : role->second;
    d.phase = w.phase;
    d.frames = w.samples;
    d.outliers[0] = w.outliers_alpha;
    d.outliers[1] = w.outliers_beta;
    d.ref[0] = w.ref_pitch_arcsec;
    d.ref[1] = w.ref_yaw_arcsec;
    d.temperature_c = w.temperature_c;
    for (int ax = 0; ax < 2 && data.reference; ++ax) {
      d.reference_terms[ax] = reference_terms_at(*data.reference, data.mount, ax, d.ref[ax], d.ref[1 - ax]);
    }
    for (int ax = 0; ax < 2 && cal; ++ax) {
      const AxisModel m = ax == 0 ? cal->alpha_model() : cal->beta_model();
      const double counts = ax == 0 ? w.counts_alpha : w.counts_beta;
      const double slope = std::fabs(rad_to_arcsec(m.slope_rad_per_count(counts)));
      d.mean[ax] = m.angle_arcsec(counts);
      d.sd[ax] = slope * (ax == 0 ? w.sd_counts_alpha : w.sd_counts_beta);
      d.sd_detrended[ax] = slope * (ax == 0 ? w.sd_detrended_counts_alpha : w.sd_detrended_counts_beta);
      d.slope[ax] = slope;
      d.noise[ax] = d.sd[ax] / std::sqrt(static_cast<double>(d.frames));
      d.quant[ax] = slope / std::sqrt(12.0);
      const double sd_ref = ax == 0 ? w.sd_ref_pitch_arcsec : w.sd_ref_yaw_arcsec;
      d.ref_noise[ax] = w.ref_readings_eff > 0 ? sd_ref / std::sqrt(w.ref_readings_eff) : 0.0;
      d.ref_readings = w.ref_readings;
      d.se[ax] = std::sqrt(sq(d.noise[ax]) + sq(d.quant[ax]) + sq(d.ref_noise[ax]));
    }
    out.push_back(d);
  }
  return out;
}

// The error budget of one dwell's mean error: sensor noise (A), quantisation (B), reference noise (A).
std::vector<BudgetEntry> dwell_budget(const DwellStats& d, int ax) {
  std::vector<BudgetEntry> b{
      {"sensor noise (mean of the dwell's frames)", 'A', d.slope[ax], d.noise[ax], dof_of(d.frames)},
      {"quantisation (one count, LSB / sqrt(12))", 'B', d.slope[ax], d.quant[ax], kInfDof}};
  if (d.ref_noise[ax] > 0) b.push_back({"reference noise (mean of the encoder readings)", 'A', -1.0, d.ref_noise[ax], dof_of(d.ref_readings)});
  return b;
}


std::optional<TemperatureSensitivity> temperature_sensitivity(const CoefficientSet* cal, int ax) {
  if (!cal || !cal->extra.contains("uncertainties")) return std::nullopt;
  const auto& un = cal->extra["uncertainties"];
  const char* key = axis_name(ax);
  if (!un.contains(key) || !un[key].is_object() || !un[key].contains("temperature")) return std::nullopt;
  const auto& t = un[key]["temperature"];
  const auto number = [&t](const char* k) {
    return t.contains(k) && t[k].is_number() ? t[k].get<double>() : std::numeric_limits<double>::quiet_NaN();
  };
  if (!t.is_object() || !std::isfinite(number("reference_c")) || !std::isfinite(number("sensitivity_arcsec_per_c"))) {
    return std::nullopt;
  }
  const double sigma = std::isfinite(number("sensitivity_sigma_arcsec_per_c")) ? number("sensitivity_sigma_arcsec_per_c") : 0.0;
  TemperatureSensitivity out{number("reference_c"), std::hypot(number("sensitivity_arcsec_per_c"), sigma)};
  if (un[key].contains("chi2_dof") && un[key]["chi2_dof"].is_number() && un[key]["chi2_dof"].get<double>() > 1) {
    out.dof = un[key]["chi2_dof"].get<double>() - 1;
  }
  return out;
}

// The temperature's entry of an angle error measured at dwells whose temperatures lie `dt_c` (RMS)
// from the calibration's: none when the recording or the calibration has no temperature.
void add_temperature(std::vector<BudgetEntry>& b, const std::optional<TemperatureSensitivity>& t, double dt_c,
                     double sensitivity, const char* what) {
  if (!t || !std::isfinite(dt_c)) return;
  b.push_back({fmt::format("temperature ({} from the calibration's {:.2f} C, at its sensitivity)", what, t->reference_c),
               'A', sensitivity * dt_c, std::abs(sensitivity * dt_c) * t->u_arcsec_per_c, t->dof});
}

// A dwell's temperature less the calibration's (NaN: either is unknown).
double temperature_offset(const DwellStats& d, const std::optional<TemperatureSensitivity>& t) {
  return t ? d.temperature_c - t->reference_c : std::numeric_limits<double>::quiet_NaN();
}

// The RMS of that over the dwells that have a temperature (NaN: none has).
double rms_temperature_offset(const std::vector<const DwellStats*>& dwells, const std::optional<TemperatureSensitivity>& t) {
  double ss = 0;
  size_t n = 0;
  for (const DwellStats* d : dwells) {
    const double dt = temperature_offset(*d, t);
    if (!std::isfinite(dt)) continue;
    ss += dt * dt;
    ++n;
  }
  return n > 0 ? std::sqrt(ss / static_cast<double>(n)) : std::numeric_limits<double>::quiet_NaN();
}

// The reference's terms: what the unit's true errors have (its calibration inherits the reference's
// error) and its measured ones, taken against the same reference, lack. A worst-of-n figure's true
// dwell is not the one the noise picked, so the terms are those of the dwell of the set where the
// reference's u is largest.
void add_reference_terms(std::vector<BudgetEntry>& b, const AcceptanceData& data,
                         const std::vector<const DwellStats*>& dwells, int ax) {
  if (!data.reference || dwells.empty()) return;
  const DwellStats* worst = nullptr;
  double worst_u = -1;
  for (const DwellStats* d : dwells) {
    if (const double u = root_sum_square(d->reference_terms[ax]); u > worst_u) {
      worst_u = u;
      worst = d;
    }
  }
  b.insert(b.end(), worst->reference_terms[ax].begin(), worst->reference_terms[ax].end());
}

// The 3-sigma accuracy over `points` is an RMS of errors each measured with its dwell's standard error
// se: the noise adds to the RMS in quadrature (E m^2 = t^2 + se^2), so the measured RMS exceeds the
// unit's by RMS - sqrt(RMS^2 - mean se^2), an effect the value is not corrected for (GUM F.2.4.5).
// The reference's own u enters the unit's true errors as the calibration inherits it: its RMS over
// the points.
void add_rms_terms(std::vector<BudgetEntry>& b, const AcceptanceData& data,
                   const std::vector<const DwellStats*>& points, int ax, double rms) {
  double se2 = 0, ref2 = 0;
  for (const DwellStats* d : points) {
    se2 += d->se[ax] * d->se[ax];
    ref2 += sq(root_sum_square(d->reference_terms[ax]));
  }
  const double n = static_cast<double>(points.size());
  const double inflation = rms - std::sqrt(std::max(0.0, rms * rms - se2 / n));
  b.push_back({"dwell-mean noise in the points' errors (it inflates the RMS)", 'A', 3.0, 3.0 * inflation, n});
  if (data.reference) {
    b.push_back({"reference calibration (RMS of its u over the points)", 'B', 3.0, 3.0 * std::sqrt(ref2 / n),
                 std::numeric_limits<double>::infinity()});
  }
}

// A worst-of-n figure is the largest |error| over dwells each measured with its standard error se:
// the noise lifts a maximum (the largest of n noisy values sits above the largest true one). The
// lift is estimated by drawing the noise again about the measured errors (a parametric bootstrap,
// seeded: the same recording gives the same budget) and is not corrected for (GUM F.2.4.5).
namespace {
constexpr int kLiftDraws = 1000;
}  // namespace

static double worst_selection_lift(const std::vector<const DwellStats*>& dwells, int ax) {
  if (dwells.size() < 2) return 0.0;
  std::mt19937_64 rng(0x5eedf00dULL + dwells.size());
  std::normal_distribution<double> z;
  double measured = 0;
  for (const DwellStats* d : dwells) measured = std::max(measured, std::abs(d->mean[ax] - d->ref[ax]));
  double sum = 0;
  for (int k = 0; k < kLiftDraws; ++k) {
    double worst = 0;
    for (const DwellStats* d : dwells) worst = std::max(worst, std::abs(d->mean[ax] - d->ref[ax] + d->se[ax] * z(rng)));
    sum += worst;
  }
  return std::max(0.0, sum / kLiftDraws - measured);
}

void add_selection_lift(std::vector<BudgetEntry>& b, const std::vector<const DwellStats*>& dwells, int ax) {
  if (dwells.size() < 2) return;
  b.push_back({fmt::format("selection of the worst of {} noisy dwells (the noise's lift of a maximum)", dwells.size()),
               'B', 1.0, worst_selection_lift(dwells, ax), std::numeric_limits<double>::infinity()});
}

}  // namespace fpss::judged
