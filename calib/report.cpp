#include "calib/report.h"

#include <fmt/format.h>

#include <cmath>

namespace fpss {
namespace {

nlohmann::json number_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::ordered_json axis_residuals(const AxisFit& a) {
  nlohmann::ordered_json j;
  j["mean_abs_arcsec"] = a.residuals.mean_abs_arcsec;
  j["sd_arcsec"] = a.residuals.sd_arcsec;
  j["max_abs_arcsec"] = a.residuals.max_abs_arcsec;
  j["points"] = a.residuals.points;
  j["range_deg"] = {a.residuals.range_deg[0], a.residuals.range_deg[1]};
  j["rms_arcsec"] = a.residuals.rms_arcsec;
  j["counts_range"] = {a.counts_range[0], a.counts_range[1]};
  return j;
}

// The GUM's figures of the listed angles: U = k u per angle, k from each angle's
// Welch-Satterthwaite degrees of freedom; the axis's coverage_factor and budget are those of the
// angle with the largest U (docs/calibration.md, "Uncertainty budget").
void add_expanded_uncertainty(nlohmann::ordered_json& ax, const AxisFit& a) {
  nlohmann::json list = nlohmann::json::array();
  for (size_t i = 0; i < a.angle_sigma_arcsec.size(); ++i) {
    const double angle = a.angle_sigma_arcsec[i][0];
    const bool has = i < a.angle_budget.size() && !a.angle_budget[i].empty();
    list.push_back({angle, has ? number_or_null(combine(a.angle_budget[i]).U) : nlohmann::json(nullptr)});
  }
  const std::optional<size_t> w = a.worst_budget_angle();
  const Combined c = w ? combine(a.angle_budget[*w]) : Combined{};
  ax["coverage_factor"] = w ? number_or_null(c.k) : nlohmann::json(nullptr);
  ax["angle_expanded_uncertainty_arcsec"] = list;
  ax["budget"] = w ? budget_json(a.angle_budget[*w], "u_arcsec") : nlohmann::ordered_json::array();
  ax["budget_angle_arcsec"] = w ? nlohmann::json(a.angle_sigma_arcsec[*w][0]) : nlohmann::json(nullptr);
  ax["dof_eff"] = w ? number_or_null(c.dof_eff) : nlohmann::json(nullptr);
  ax["expanded_uncertainty_max_arcsec"] = w ? number_or_null(c.U) : nlohmann::json(nullptr);
}

// The sensor's temperature over the fit's dwells and its fitted sensitivity: the calibration holds at
// reference_c (null: the recording has no temperature).
nlohmann::json temperature_json(const fit::TemperatureInfluence& t) {
  if (!t.known) return nullptr;
  nlohmann::ordered_json j;
  j["reference_c"] = t.reference_c;
  j["spread_c"] = t.spread_c;
  j["dwells"] = t.dwells;
  j["sensitivity_arcsec_per_c"] = t.sensitivity_arcsec_per_c;
  j["sensitivity_sigma_arcsec_per_c"] = number_or_null(t.sensitivity_sigma);
  return j;
}

}  // namespace

nlohmann::json residuals_json(const CalibrationReport& r) {
  nlohmann::ordered_json j;
  j["pitch"] = axis_residuals(r.pitch);
  j["yaw"] = axis_residuals(r.yaw);
  return j;
}

nlohmann::json uncertainties_json(const CalibrationReport& r) {
  nlohmann::ordered_json j;
  for (const AxisFit* a : {&r.pitch, &r.yaw}) {
    nlohmann::json s = nlohmann::json::array();
    for (double v : a->sigma) s.push_back(number_or_null(v));
    j[a->coefficient_key] = s;
  }
  for (const AxisFit* a : {&r.pitch, &r.yaw}) {
    nlohmann::ordered_json ax;
    ax["angle_sigma_max_arcsec"] = number_or_null(a->angle_sigma_max_arcsec);
    nlohmann::json list = nlohmann::json::array();
    for (const auto& [angle, sigma] : a->angle_sigma_arcsec) list.push_back({angle, number_or_null(sigma)});
    ax["angle_sigma_arcsec"] = list;
    add_expanded_uncertainty(ax, *a);
    ax["fit"] = a->fit_form;
    ax["reduced_chi2"] = number_or_null(a->reduced_chi2);
    ax["chi2_dof"] = a->chi2_dof;
    ax["model_remainder"] = a->model_remainder;
    ax["sigma_scale"] = a->sigma_scale;
    ax["count_noise_counts"] = number_or_null(a->noise.count_noise_counts);
    ax["count_noise_source"] = a->noise.count_noise_source;
    ax["ref_noise_arcsec"] = number_or_null(a->noise.ref_noise_arcsec);
    ax["quantisation_corrected"] = a->noise.quantisation_corrected;
    if (std::isfinite(a->reference_u_max_arcsec)) ax["reference_u_max_arcsec"] = a->reference_u_max_arcsec;
    ax["temperature"] = temperature_json(a->temperature);
    ax["pseudo_inverse"] = a->covariance_pseudo_inverse;
    ax["covariance"] = a->covariance_note;
    j[a->axis] = ax;
  }
  return j;
}

nlohmann::json solver_json(const CalibrationReport& r) {
  nlohmann::ordered_json j;
  for (const AxisFit* a : {&r.pitch, &r.yaw}) {
    nlohmann::ordered_json s;
    s["start"] = a->solver.start;
    s["candidates"] = a->solver.candidates;
    s["grid_rows"] = a->solver.grid_rows;
    s["grid_rms_arcsec"] = number_or_null(a->solver.grid_rms_arcsec);
    s["iterations"] = a->solver.iterations;
    s["initial_cost"] = a->solver.initial_cost;
    s["final_cost"] = a->solver.final_cost;
    s["converged"] = a->solver.converged;
    s["gls_iterations"] = a->solver.gls_iterations;
    s["gls_converged"] = a->solver.gls_converged;
    s["brief"] = a->solver.brief;
    j[a->axis] = s;
  }
  return j;
}

CoefficientSet CalibrationReport::coefficients() const {
  CoefficientSet s;
  s.unit = unit;
  s.alpha = pitch.coeffs;
  s.beta = yaw.coeffs;
  s.extra["kind"] = "fitted";
  s.extra["method"] = std::string(to_string(method));
  s.extra["source"] = source;
  s.extra["samples"] = samples;
  s.extra["dwells"] = {{"null", null_dwells}, {"offset", offset_dwells}, {"pairs", pairs}, {"outlier_frames", outliers.any.outlier_frames}};
  s.extra["outliers"] = outliers.to_json();
  s.extra["residuals"] = residuals_json(*this);
  s.extra["uncertainties"] = uncertainties_json(*this);
  s.extra["solver"] = solver_json(*this);
  if (reference) s.extra["reference"] = *reference;
  return s;
}

namespace {

// What the summary's head shows of a fit, from a report in memory or from a coefficient file.
struct SummaryHead {
  std::string unit, source, method;
  bool differences = false;
  size_t samples = 0, null_dwells = 0, offset_dwells = 0, pairs = 0;
  struct Axis {
    std::string name;  // "pitch (alpha)"
    ResidualStats residuals;
    AxisCoeffs coeffs{};
    std::array<double, 8> sigma{};
  };
  std::array<Axis, 2> axes;
};

// The first line, Table 1 and the coefficients with their 1-sigma: one form for both sources.
std::string head_text(const SummaryHead& h) {
  std::string o;
  o += fmt::format("Calibration{} from {} (method: {}; {} samples, {} null and {} offset dwells{})\n\n",
                   h.unit.empty() ? "" : " of " + h.unit, h.source.empty() ? "samples" : h.source, h.method,
                   h.samples, h.null_dwells, h.offset_dwells,
                   h.differences ? fmt::format(", {} changes", h.pairs) : "");
  o += fmt::format("{:<15} {:>16}  {:>22}  {:>15}  {:>7}\n", "axis", "range (deg)", "mean residual (arcsec)",
                   "max (arcsec)", "points");
  for (const auto& a : h.axes) {
    o += fmt::format("{:<15} {:>7.2f} to {:<5.2f}  {:>13.2f} +- {:<5.2f}  {:>15.2f}  {:>7}\n", a.name,
                     a.residuals.range_deg[1], a.residuals.range_deg[0], a.residuals.mean_abs_arcsec,
                     a.residuals.sd_arcsec, a.residuals.max_abs_arcsec, a.residuals.points);
  }
  o += fmt::format("\n{:<4} {:>30}  {:>30}\n", "", "alpha (pitch) +- 1 sigma", "beta (yaw) +- 1 sigma");
  for (int i = 0; i < 8; ++i) {
    o += fmt::format("C{:<3} {:>16.7e} +- {:<10.2e}  {:>16.7e} +- {:<10.2e}\n", i + 1, h.axes[0].coeffs[i],
                     h.axes[0].sigma[i], h.axes[1].coeffs[i], h.axes[1].sigma[i]);
  }
  o += "(radians, N in counts)\n\n";
  return o;
}

SummaryHead head_of(const CalibrationReport& r) {
  SummaryHead h{r.unit, r.source, std::string(to_string(r.method)), r.method == Method::differences, r.samples,
                r.null_dwells, r.offset_dwells, r.pairs, {}};
  size_t k = 0;
  for (const AxisFit* a : {&r.pitch, &r.yaw}) {
    h.axes[k++] = {fmt::format("{} ({})", a->axis, a->coefficient_key), a->residuals, a->coeffs, a->sigma};
  }
  return h;
}

// A number of a coefficient file's block; NaN where it is null or absent (as the fit had it).
double number_in(const nlohmann::json& j, const char* key) {
  return j.is_object() && j.contains(key) && j[key].is_number() ? j[key].get<double>() : std::nan("");
}

size_t count_in(const nlohmann::json& j, const char* key) {
  return j.is_object() && j.contains(key) && j[key].is_number_unsigned() ? j[key].get<size_t>() : 0;
}

ResidualStats residuals_of(const nlohmann::json& j) {
  ResidualStats s;
  s.mean_abs_arcsec = number_in(j, "mean_abs_arcsec");
  s.sd_arcsec = number_in(j, "sd_arcsec");
  s.max_abs_arcsec = number_in(j, "max_abs_arcsec");
  s.rms_arcsec = number_in(j, "rms_arcsec");
  s.points = count_in(j, "points");
  const nlohmann::json range = j.is_object() ? j.value("range_deg", nlohmann::json()) : nlohmann::json();
  if (range.is_array() && range.size() == 2 && range[0].is_number() && range[1].is_number()) {
    s.range_deg = {range[0].get<double>(), range[1].get<double>()};
  }
  return s;
}

std::array<double, 8> sigma_of(const nlohmann::json& list) {
  std::array<double, 8> s;
  s.fill(std::nan(""));
  for (size_t i = 0; list.is_array() && i < list.size() && i < 8; ++i) {
    if (list[i].is_number()) s[i] = list[i].get<double>();
  }
  return s;
}

}  // namespace

std::string summary_text(const CoefficientSet& fitted) {
  const nlohmann::json& x = fitted.extra;
  if (!x.is_object() || !x.contains("residuals") || !x["residuals"].is_object()) return {};
  const nlohmann::json dwells = x.value("dwells", nlohmann::json::object());
  const nlohmann::json sigmas = x.value("uncertainties", nlohmann::json::object());
  SummaryHead h;
  h.unit = fitted.unit;
  h.source = x.value("source", "");
  h.method = x.value("method", "");
  h.differences = h.method == to_string(Method::differences);
  h.samples = count_in(x, "samples");
  h.null_dwells = count_in(dwells, "null");
  h.offset_dwells = count_in(dwells, "offset");
  h.pairs = count_in(dwells, "pairs");
  h.axes[0] = {"pitch (alpha)", residuals_of(x["residuals"].value("pitch", nlohmann::json())), fitted.alpha,
               sigma_of(sigmas.value("alpha", nlohmann::json()))};
  h.axes[1] = {"yaw (beta)", residuals_of(x["residuals"].value("yaw", nlohmann::json())), fitted.beta,
               sigma_of(sigmas.value("beta", nlohmann::json()))};
  return head_text(h);
}

std::string summary_text(const CalibrationReport& r) {
  std::string o = head_text(head_of(r));
  for (const AxisFit* a : {&r.pitch, &r.yaw}) {
    o += fmt::format("{}: 1-sigma of the fitted angle over counts [{:.0f}, {:.0f}]: at most {:.3f} arcsec{}\n",
                     a->axis, a->counts_range[0], a->counts_range[1], a->angle_sigma_max_arcsec,
                     a->covariance_pseudo_inverse ? " (pseudo-inverse: J^T J rank deficient)" : "");
  }
  if (r.reference) {
    o += fmt::format("reference {} (certificate {}, {}, {}; sha256 {}), {}: its u included, at most {:.3f} "
                     "(pitch) and {:.3f} (yaw) arcsec\n",
                     r.reference->value("file", ""), r.reference->value("certificate", ""), r.reference->value("date", ""),
                     r.reference->value("lab", ""), r.reference->value("sha256", ""),
                     r.reference->value("corrected_by", "") == "calibrate" ? "applied to the reference angles"
                                                                            : "applied by the run",
                     r.pitch.reference_u_max_arcsec, r.yaw.reference_u_max_arcsec);
  }
  for (const AxisFit* a : {&r.pitch, &r.yaw}) {
    if (a->fit_form != FitForm::gls) continue;
    o += fmt::format("{}: GLS of the changes over {} dwells; count noise {} ({}{}), reference noise {:.3f} arcsec; "
                     "chi2/dof {:.2f} ({} dof){}\n",
                     a->axis, a->dwells_fitted,
                     std::isfinite(a->noise.count_noise_counts) ? fmt::format("{:.3f} counts", a->noise.count_noise_counts) : "unknown",
                     a->noise.count_noise_source, a->noise.quantisation_corrected ? ", quantisation corrected" : "",
                     a->noise.ref_noise_arcsec, a->reduced_chi2, a->chi2_dof,
                     a->model_remainder ? fmt::format(": MODEL REMAINDER, sigmas scaled by {:.2f}", a->sigma_scale) : "");
  }
  if (r.outliers.any.outlier_frames > 0) {
    const auto& u = r.outliers;
    o += fmt::format("{} of {} frames ({:.2f} %) were outliers, left out of the dwell means: pitch {} ({:.2f} %), "
                     "yaw {} ({:.2f} %)\n",
                     u.any.outlier_frames, u.frames, 100 * u.any.share(u.frames), u.alpha.outlier_frames,
                     100 * u.alpha.share(u.frames), u.beta.outlier_frames, 100 * u.beta.share(u.frames));
  }
  for (const AxisFit* a : {&r.pitch, &r.yaw}) {
    o += fmt::format("{}: start {} (best of {}); {}\n", a->axis, a->solver.start, a->solver.candidates,
                     a->solver.brief);
  }
  return o;
}

TruthComparison compare_to_truth(const CalibrationReport& r, const CoefficientSet& truth) {
  TruthComparison t;
  t.pitch = compare_transfer(r.pitch.coeffs, truth.alpha, r.pitch.counts_range[0], r.pitch.counts_range[1]);
  t.yaw = compare_transfer(r.yaw.coeffs, truth.beta, r.yaw.counts_range[0], r.yaw.counts_range[1]);
  return t;
}

std::string truth_text(const TruthComparison& t, const std::string& truth_name) {
  std::string o = fmt::format("\nFit minus truth ({}) over the calibrated count range:\n", truth_name);
  o += fmt::format("  pitch (alpha): max {:.4f} arcsec (at N = {:.0f}), rms {:.4f} arcsec\n", t.pitch.max_abs_arcsec,
                   t.pitch.at_counts, t.pitch.rms_arcsec);
  o += fmt::format("  yaw (beta):    max {:.4f} arcsec (at N = {:.0f}), rms {:.4f} arcsec\n", t.yaw.max_abs_arcsec,
                   t.yaw.at_counts, t.yaw.rms_arcsec);
  return o;
}

}  // namespace fpss
