#include "calib/monte_carlo.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <stdexcept>

#include "calib/reference_fit.h"
#include "calib/units.h"

namespace fpss {

namespace {

// Every term of `nominal` drawn from N(value, u) into `drawn` (a copy of it made once: the trials
// reuse it, so none copies the file's names and texts again).
void redraw(const ReferenceCalibration& nominal, ReferenceCalibration& drawn, std::mt19937_64& rng,
            std::normal_distribution<double>& z) {
  const auto draw = [&](const CertifiedValue& from, CertifiedValue& to) { to.value = from.value + from.u * z(rng); };
  for (auto [from, to] : {std::pair{&nominal.pitch, &drawn.pitch}, std::pair{&nominal.yaw, &drawn.yaw}}) {
    draw(from->scale_factor_ppm, to->scale_factor_ppm);
    draw(from->nonorthogonality_arcsec, to->nonorthogonality_arcsec);
    draw(from->zero_arcsec, to->zero_arcsec);
    for (size_t c = 0; c < from->cyclic.size(); ++c) {
      draw(from->cyclic[c].amplitude_arcsec, to->cyclic[c].amplitude_arcsec);
      draw(from->cyclic[c].phase_rad, to->cyclic[c].phase_rad);
    }
  }
}

// The value at probability p of sorted draws (linear between order statistics).
double quantile(const std::vector<double>& sorted, double p) {
  const double x = p * static_cast<double>(sorted.size() - 1);
  const size_t i = static_cast<size_t>(std::floor(x));
  const double f = x - static_cast<double>(i);
  return i + 1 < sorted.size() ? sorted[i] * (1 - f) + sorted[i + 1] * f : sorted.back();
}

// JCGM 101 8.2: u written to two significant digits as c x 10^l; the tolerance is 10^l / 2.
double numerical_tolerance(double u) {
  if (!(u > 0)) return 0;
  const double l = std::floor(std::log10(u)) - 1;
  return 0.5 * std::pow(10.0, l);
}

MonteCarloAxis check_axis(const AxisFit& a, int sensor_axis, const CalibrationReport& rep,
                          const CalibrationOptions& opts, size_t trials, std::mt19937_64& rng) {
  MonteCarloAxis out;
  out.axis = a.axis;
  const size_t i = *a.worst_budget_angle();
  out.angle_arcsec = a.angle_sigma_arcsec[i][0];
  const Combined gum = combine(a.angle_budget[i]);
  out.gum_u_arcsec = gum.u;
  out.gum_expanded_arcsec = gum.U;
  // The fit's sources to first order: the coefficients' covariance is a linearisation, and drawing
  // the coefficients themselves leaves the region where it holds (a slow sinusoid trades with the
  // slope along a curved valley: measured, a 66 arcsec spread on a fit whose angle sigma is 0.03).
  // Student's t for finite degrees of freedom (JCGM 101 6.4.9): the normal over sqrt(chi2 / dof).
  struct Source {
    double u, dof;
    std::optional<std::chi_squared_distribution<double>> chi2;
  };
  // The temperature's entry follows the fit's sources (angle_budget.cpp fit_budget); drawn the same
  // way, about zero: its u stands for an effect the fit did not correct.
  std::vector<Source> sources;
  const size_t drawn_entries = a.covariance_sources.size() + (a.temperature.known ? 1 : 0);
  for (size_t k = 0; k < drawn_entries && k < a.angle_budget[i].size(); ++k) {
    const BudgetEntry& e = a.angle_budget[i][k];
    sources.push_back({e.u, e.dof, std::isfinite(e.dof) ? std::optional(std::chi_squared_distribution<double>(e.dof))
                                                        : std::nullopt});
  }
  const ReferenceCalibration* ref = opts.reference ? &*opts.reference : nullptr;
  std::optional<ReferenceCalibration> drawn;
  double other = 0, ref_nominal = 0;
  if (ref) {
    const double extent = other_axis_extent_arcsec(rep, sensor_axis);
    other = reference_worst_other_arcsec(*ref, opts.mount, sensor_axis, out.angle_arcsec, extent);
    ref_nominal = reference_error_arcsec(*ref, opts.mount, sensor_axis, out.angle_arcsec, other);
    drawn = *ref;
  }

  std::normal_distribution<double> z;
  std::vector<double> err(trials);
  for (size_t t = 0; t < trials; ++t) {
    double e = 0;
    for (Source& s : sources) {
      const double scale = s.chi2 ? std::sqrt(s.dof / (*s.chi2)(rng)) : 1.0;
      e += s.u * scale * z(rng);
    }
    if (ref) {
      redraw(*ref, *drawn, rng, z);
      e += reference_error_arcsec(*drawn, opts.mount, sensor_axis, out.angle_arcsec, other) - ref_nominal;
    }
    err[t] = e;
  }
  double sum = 0, sum2 = 0;
  for (double e : err) sum += e;
  out.mean_arcsec = sum / static_cast<double>(trials);
  for (double e : err) sum2 += (e - out.mean_arcsec) * (e - out.mean_arcsec);
  out.u_arcsec = std::sqrt(sum2 / static_cast<double>(trials - 1));
  std::sort(err.begin(), err.end());
  out.low_arcsec = quantile(err, 0.025);
  out.high_arcsec = quantile(err, 0.975);
  out.d_low_arcsec = std::abs(-gum.U - out.low_arcsec);
  out.d_high_arcsec = std::abs(gum.U - out.high_arcsec);
  out.tolerance_arcsec = numerical_tolerance(gum.u);
  out.gum_validated = out.d_low_arcsec <= out.tolerance_arcsec && out.d_high_arcsec <= out.tolerance_arcsec;
  return out;
}

}  // namespace

MonteCarloCheck monte_carlo_check(const CalibrationReport& rep, const CalibrationOptions& opts, size_t trials,
                                  uint64_t seed) {
  if (trials < 100 || trials > 10'000'000) {
    throw std::invalid_argument(fmt::format("--monte-carlo {}: expected 100 to 10000000 trials", trials));
  }
  MonteCarloCheck mc;
  mc.trials = trials;
  mc.seed = seed;
  std::mt19937_64 rng(seed);
  int sensor_axis = 0;
  for (const AxisFit* a : {&rep.pitch, &rep.yaw}) {
    if (a->worst_budget_angle()) mc.axes.push_back(check_axis(*a, sensor_axis, rep, opts, trials, rng));
    ++sensor_axis;
  }
  return mc;
}

nlohmann::ordered_json MonteCarloCheck::to_json() const {
  nlohmann::ordered_json j;
  j["method"] = "JCGM 101 (propagation of distributions)";
  j["trials"] = trials;
  j["seed"] = seed;
  for (const MonteCarloAxis& a : axes) {
    j[a.axis] = {{"angle_arcsec", a.angle_arcsec},
                 {"mean_arcsec", a.mean_arcsec},
                 {"u_arcsec", a.u_arcsec},
                 {"interval_95_arcsec", {a.low_arcsec, a.high_arcsec}},
                 {"gum_u_arcsec", a.gum_u_arcsec},
                 {"gum_expanded_uncertainty_arcsec", a.gum_expanded_arcsec},
                 {"d_low_arcsec", a.d_low_arcsec},
                 {"d_high_arcsec", a.d_high_arcsec},
                 {"tolerance_arcsec", a.tolerance_arcsec},
                 {"gum_validated", a.gum_validated}};
  }
  return j;
}

namespace {

// What the comparison means for the U calibration.json states: validated, or which way U errs, by
// how much against U itself (a miss of a few per cent at the tolerance of u's second digit is not
// one of a factor), and which figure to quote.
std::string validation_text(const MonteCarloAxis& a) {
  if (a.gum_validated) return "the GUM budget is validated: its U holds as stated";
  const double worst = std::max(a.d_low_arcsec, a.d_high_arcsec);
  const bool wider = a.gum_expanded_arcsec > (a.high_arcsec - a.low_arcsec) / 2;
  const double share = a.gum_expanded_arcsec > 0 ? 100 * worst / a.gum_expanded_arcsec : 100;
  return fmt::format("the GUM budget is NOT validated: its +-U is {} than the Monte Carlo 95 % interval by up to "
                     "{:.4f} arcsec ({:.1f} % of U), beyond the tolerance; {}",
                     wider ? "wider" : "narrower", worst, share,
                     wider ? "U overstates this angle's uncertainty (safe but conservative): the interval above is "
                             "the tighter figure to quote"
                           : "U understates this angle's uncertainty: quote the interval above, not U");
}

}  // namespace

std::string monte_carlo_text(const MonteCarloCheck& mc) {
  std::string s = fmt::format("\nMonte Carlo check of the budget (JCGM 101, {} trials, seed {}):\n", mc.trials, mc.seed);
  for (const MonteCarloAxis& a : mc.axes) {
    s += fmt::format("  {:<5} at {:.1f} arcsec: u {:.4f} (GUM {:.4f}), 95 % [{:.4f}, {:.4f}] (GUM +-{:.4f}); "
                     "d_low {:.4f}, d_high {:.4f} against {:.4f}: {}\n",
                     a.axis, a.angle_arcsec, a.u_arcsec, a.gum_u_arcsec, a.low_arcsec, a.high_arcsec,
                     a.gum_expanded_arcsec, a.d_low_arcsec, a.d_high_arcsec, a.tolerance_arcsec, validation_text(a));
  }
  return s;
}

}  // namespace fpss
