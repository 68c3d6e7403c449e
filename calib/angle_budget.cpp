#include "calib/angle_budget.h"

#include <cmath>
#include <limits>

#include "calib/units.h"

namespace fpss::fit {
namespace {

// The temperature's entry at `counts`: the fit moved by kappa x shift (TemperatureInfluence).
std::optional<BudgetEntry> temperature_entry(const AxisFit& out, double counts) {
  const fit::TemperatureInfluence& t = out.temperature;
  if (!t.known) return std::nullopt;
  const double sens = fit::angle_shift_arcsec(t.shift_scaled, out.coeffs, counts);
  return BudgetEntry{"temperature (its spread over the recording, at the fitted sensitivity)", 'A', sens,
                     std::abs(sens) * t.u_per_shift(), t.dof};
}

std::vector<BudgetEntry> fit_budget(const AxisFit& out, double counts) {
  std::vector<BudgetEntry> b;
  for (const auto& s : out.covariance_sources) {
    b.push_back({s.source, s.type, 1.0, angle_sigma_arcsec(s.covariance_scaled, out.coeffs, counts), s.dof});
  }
  if (auto t = temperature_entry(out, counts)) b.push_back(*t);
  return b;
}

// The fit's angle sigma at `counts` with the temperature's entry beside it.
double angle_sigma_with_temperature(const AxisFit& out, const Uncertainty& u, double counts) {
  const double sig = angle_sigma_arcsec(u, out.coeffs, counts);
  const auto t = temperature_entry(out, counts);
  return t ? std::hypot(sig, t->u) : sig;
}

}  // namespace

std::vector<AxisFit::CovarianceSource> covariance_sources(const AxisFit& out, const Uncertainty& u, const AxisData& d) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const auto dof_or_inf = [](double dof) { return dof > 0 ? dof : kInf; };
  const double fit_dof = out.fit_form == FitForm::gls ? static_cast<double>(out.chi2_dof)
                                                       : static_cast<double>(d.rows()) - static_cast<double>(d.parameters());
  if (!u.sources_known) return {{"model and fit", 'A', dof_or_inf(fit_dof), u.covariance_scaled}};
  const auto& c = u.source_covariance_scaled;
  const bool sensor_from_data = out.noise.count_noise_source == "within-dwell scatter";
  return {
      {"sensor noise", sensor_from_data ? 'A' : 'B', sensor_from_data ? dof_or_inf(d.scatter_dof) : kInf,
       c[static_cast<size_t>(NoiseSource::sensor)]},
      {"quantisation", 'B', kInf, c[static_cast<size_t>(NoiseSource::quantisation)]},
      {"reference noise", 'A', dof_or_inf(d.ref_scatter_dof), c[static_cast<size_t>(NoiseSource::reference)]},
      {"model and fit", 'A', dof_or_inf(fit_dof),
       (c[0] + c[1] + c[2]) * std::max(0.0, out.sigma_scale * out.sigma_scale - 1.0)},
  };
}


void list_angle_sigmas(AxisFit& out, const Uncertainty& u, const AxisData& d, int count,
                       const std::optional<std::array<double, 2>>& range_arcsec) {
  out.angle_sigma_arcsec.clear();
  out.angle_budget.clear();
  if (count < 2) return;
  const AxisModel model(out.coeffs);
  const double lo = range_arcsec ? (*range_arcsec)[0] : d.ref_lo_arcsec;
  const double hi = range_arcsec ? (*range_arcsec)[1] : d.ref_hi_arcsec;
  // Beyond the data (a range asked for) the counts are searched as far again as the angles lie
  // outside it, at the nominal scale factor, with room to spare.
  const double outside_arcsec = std::max({0.0, d.ref_lo_arcsec - lo, hi - d.ref_hi_arcsec});
  const double margin = 0.05 * (d.counts_hi - d.counts_lo) + 10 + 2 * outside_arcsec / (kNominalC2 * kArcsecPerRad);
  for (int i = 0; i < count; ++i) {
    const double a = lo + (hi - lo) * i / (count - 1);
    double sig = std::numeric_limits<double>::quiet_NaN();
    std::vector<BudgetEntry> budget;
    try {
      const double n = model.counts_for_angle_unchecked(arcsec_to_rad(a), d.counts_lo - margin, d.counts_hi + margin);
      sig = angle_sigma_with_temperature(out, u, n);
      budget = fit_budget(out, n);
    } catch (const std::exception&) {
      // not reached within the range: listed as null
    }
    out.angle_sigma_arcsec.push_back({a, sig});
    out.angle_budget.push_back(std::move(budget));
  }
}

}  // namespace fpss::fit
