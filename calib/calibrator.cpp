#include "calib/calibrator.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <thread>

#include "base/errors.h"
#include "calib/angle_budget.h"
#include "calib/outliers.h"
#include "calib/quantisation.h"
#include "calib/reference_fit.h"
#include "calib/refine.h"
#include "calib/units.h"

namespace fpss {

std::string_view to_string(Method m) { return m == Method::differences ? "differences" : "absolute"; }

std::optional<Method> parse_method(std::string_view s) {
  if (s == "differences") return Method::differences;
  if (s == "absolute") return Method::absolute;
  return std::nullopt;
}

TransferDifference compare_transfer(const AxisCoeffs& a, const AxisCoeffs& b, double lo, double hi, int steps) {
  TransferDifference out;
  double sum_sq = 0;
  for (int i = 0; i <= steps; ++i) {
    const double n = lo + (hi - lo) * i / steps;
    const double d = rad_to_arcsec(transfer_angle(a.data(), n) - transfer_angle(b.data(), n));
    sum_sq += d * d;
    if (std::abs(d) > out.max_abs_arcsec) {
      out.max_abs_arcsec = std::abs(d);
      out.at_counts = n;
    }
  }
  out.rms_arcsec = std::sqrt(sum_sq / (steps + 1));
  return out;
}

namespace fit {
namespace {

// An axis whose counts move less than this between null and offset was not calibrated along.
constexpr double kMinSpreadCounts = 200.0;  // ~22 arcsec
// Offset positions closer than this are one position for telling the coefficients apart.
constexpr double kDistinctCounts = 50.0;
// Grid local minima refined only when their cost is within this factor of the best node's.
constexpr double kKeepCostRatio = 10.0;
constexpr int kScreenIterations = 50;
constexpr size_t kRowsPerThreadMin = 20000;

const char* axis_name(Axis a) { return a == Axis::alpha ? "pitch" : "yaw"; }
const char* counts_column(Axis a) { return a == Axis::alpha ? "counts_alpha" : "counts_beta"; }
double counts_of(const Dwell& d, Axis a) { return a == Axis::alpha ? d.counts_alpha : d.counts_beta; }
double ref_of(const Dwell& d, Axis a) { return a == Axis::alpha ? d.ref_pitch_arcsec : d.ref_yaw_arcsec; }

}  // namespace

namespace {

double sd_counts_of(const Dwell& d, Axis a) { return a == Axis::alpha ? d.sd_counts_alpha : d.sd_counts_beta; }
double sd_ref_of(const Dwell& d, Axis a) { return a == Axis::alpha ? d.sd_ref_pitch_arcsec : d.sd_ref_yaw_arcsec; }
bool whole_of(const Dwell& d, Axis a) { return a == Axis::alpha ? d.whole_counts_alpha : d.whole_counts_beta; }

// The dwell's row (found by step among the latest rows: pairs and nulls arrive in recording order),
// added when new; a new dwell's scatter enters the pooled sums.
uint32_t dwell_row(AxisData& d, Axis axis, const Dwell& dw) {
  constexpr size_t kLook = AxisData::kRecentSteps;
  const size_t n = d.dwells.size();
  for (size_t k = n; k > 0 && n - k < kLook; --k) {
    if (d.recent_steps[(k - 1) % kLook] == dw.step) return static_cast<uint32_t>(k - 1);
  }
  AxisData::DwellRow r;
  r.counts = counts_of(dw, axis);
  r.ref_arcsec = ref_of(dw, axis);
  r.link = static_cast<uint32_t>(n);
  r.info = AxisData::DwellRow::pack(dw.samples, dw.ref_readings_eff, dw.phase == Phase::null, whole_of(dw, axis));
  d.dwells.push_back(r);
  d.dwell_temperature_c.push_back(static_cast<float>(dw.temperature_c));
  d.recent_steps[n % kLook] = dw.step;
  // The scatter as float (what a dwell record used to keep): the pooled sums stay as they were.
  const double sd_counts = static_cast<float>(sd_counts_of(dw, axis));
  const double sd_ref = static_cast<float>(sd_ref_of(dw, axis));
  d.all_whole_counts = d.all_whole_counts && r.whole_counts();
  if (r.samples() >= 2) {
    const double f = r.samples() - 1.0;
    d.count_scatter_ss += f * sd_counts * sd_counts;
    d.scatter_dof += f;
    d.count_scatter.add({r.counts, sd_counts * sd_counts, r.samples()});
  }
  // The reference's scatter over its readings (frames sharing one repeat it).
  if (dw.ref_readings >= 2) {
    const double f = static_cast<double>(dw.ref_readings) - 1.0;
    d.ref_scatter_ss += f * sd_ref * sd_ref;
    d.ref_scatter_dof += f;
  }
  return static_cast<uint32_t>(n);
}

uint32_t root_of(std::deque<AxisData::DwellRow>& rows, uint32_t k) {
  while (rows[k].link != k) {
    rows[k].link = rows[rows[k].link].link;  // path halving
    k = rows[k].link;
  }
  return k;
}

}  // namespace

void add_pair_rows(AxisData& d, Axis axis, const Dwell& null_dwell, const Dwell& offset_dwell) {
  const uint32_t nk = dwell_row(d, axis, null_dwell), ok = dwell_row(d, axis, offset_dwell);
  const uint32_t a = root_of(d.dwells, nk);
  const uint32_t b = root_of(d.dwells, ok);
  d.dwells[std::max(a, b)].link = std::min(a, b);
  d.changes.push_back({nk, ok});
  d.cover(counts_of(offset_dwell, axis), ref_of(offset_dwell, axis));
  d.cover(counts_of(null_dwell, axis), ref_of(null_dwell, axis));
}

void add_null(AxisData& d, Axis axis, const Dwell& null_dwell) {
  dwell_row(d, axis, null_dwell);
  d.null_counts_sum += counts_of(null_dwell, axis);
  d.null_ref_arcsec_sum += ref_of(null_dwell, axis);
  ++d.null_dwells;
  d.cover(counts_of(null_dwell, axis), ref_of(null_dwell, axis));
}

void add_absolute_row(AxisData& d, Axis axis, const Dwell& dwell) {
  d.n_plus.push_back(counts_of(dwell, axis));
  d.y_arcsec.push_back(ref_of(dwell, axis));
  d.cover(counts_of(dwell, axis), ref_of(dwell, axis));
}

void check_axis(const AxisData& d, Axis axis, const std::string& origin) {
  const std::string where = fmt::format("{}: {} axis ({})", origin.empty() ? "samples" : origin,
                                        axis_name(axis), counts_column(axis));
  const size_t p = d.parameters();
  const char* what = d.differences ? "changes null <-> offset" : "dwells";
  if (d.rows() == 0) throw DataError(fmt::format("{}: no {}: nothing to fit", where, what));
  double spread = 0, ref_spread = 0;
  if (d.differences) {
    for (size_t i = 0; i < d.rows(); ++i) {
      spread = std::max(spread, std::abs(d.row_n_plus(i) - d.row_n_minus(i)));
      ref_spread = std::max(ref_spread, std::abs(d.row_y_arcsec(i)));
    }
  } else {
    spread = d.counts_hi - d.counts_lo;
    ref_spread = d.ref_hi_arcsec - d.ref_lo_arcsec;
  }
  if (spread < kMinSpreadCounts) {
    throw DataError(fmt::format(
        "{}: no offsets along {}: the counts move by at most {:.0f} counts ({:.1f} arcsec of reference) "
        "across the recording, so the {} transfer function cannot be told from this data; a calibration "
        "needs offsets along both pitch and yaw",
        where, axis_name(axis), spread, ref_spread, axis_name(axis)));
  }
  // Positions at least kDistinctCounts from the last one counted: a dense scan counts by its
  // extent, a few positions repeated many times count once each.
  std::vector<double> pos(d.rows());
  for (size_t i = 0; i < d.rows(); ++i) pos[i] = d.row_n_plus(i);
  std::sort(pos.begin(), pos.end());
  size_t distinct = 0;
  double last = 0;
  for (double n : pos) {
    if (distinct == 0 || n - last > kDistinctCounts) {
      ++distinct;
      last = n;
    }
  }
  const size_t need = p + 1;
  if (distinct < need || d.rows() < p + 2) {
    throw DataError(fmt::format(
        "{}: too few points: {} {} at {} distinct positions (>{:.0f} counts apart); at least {} positions "
        "and {} {} are needed to tell the {} coefficients {} apart",
        where, d.rows(), what, distinct, kDistinctCounts, need, p + 2, what, p,
        d.differences ? "C2..C8" : "C1..C8"));
  }
  if (d.differences && d.null_dwells == 0) {
    throw DataError(fmt::format("{}: no null dwells: C1 follows from the null condition", where));
  }
}

namespace {

struct Prepared {
  GlsData g;
  NoiseInfo noise;
};

std::optional<double> noise_from_file(const CalibrationOptions& opts) {
  if (!opts.init || !opts.init->extra.is_object() || !opts.init->extra.contains("count_noise_counts")) return std::nullopt;
  const auto& v = opts.init->extra.at("count_noise_counts");
  if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < 0) {
    throw DataError(fmt::format("start set{}: \"count_noise_counts\": expected a number >= 0 (counts), got {}",
                                opts.init->unit.empty() ? "" : " of " + opts.init->unit, v.dump()));
  }
  return v.get<double>();
}

// The dwells with their counts' and references' variances (the noise model), and the levels.
Prepared prepare_gls(const AxisData& d, const CalibrationOptions& opts) {
  Prepared p;
  NoiseInfo& ni = p.noise;
  std::optional<double> s;
  if (opts.count_noise_counts) {
    if (!std::isfinite(*opts.count_noise_counts) || *opts.count_noise_counts < 0) {
      throw DataError(fmt::format("count noise {} counts: expected a number >= 0", *opts.count_noise_counts));
    }
    s = *opts.count_noise_counts;
    ni.count_noise_source = opts.count_noise_source;
  } else if ((s = noise_from_file(opts))) {
    ni.count_noise_source = "coefficient file";
  }
  const bool whole = d.all_whole_counts;
  const double ref_dof = d.ref_scatter_dof, raw_dof = d.scatter_dof;
  if (!s) {
    if (whole) s = d.count_scatter.estimate();
    else if (raw_dof > 0) s = std::sqrt(d.count_scatter_ss / raw_dof);
    if (s) ni.count_noise_source = "within-dwell scatter";
  }
  const double ref_var = ref_dof > 0 ? d.ref_scatter_ss / ref_dof : std::nan("");
  if (s) ni.count_noise_counts = *s;
  if (ref_dof > 0) ni.ref_noise_arcsec = std::sqrt(ref_var);
  ni.quantisation_corrected = opts.quantisation_correction && s && whole && *s >= kMinQuantisationNoise;

  GlsData& g = p.g;
  g.dwells = &d.dwells;
  g.noise_known = s.has_value() && ref_dof > 0;
  g.ref_var_arcsec2 = std::isfinite(ref_var) ? ref_var : 0.0;
  const auto& temp = d.dwell_temperature_c;
  if (std::any_of(temp.begin(), temp.end(), [](float t) { return std::isfinite(t); })) g.temperature_c = &temp;
  const size_t m = d.dwells.size();
  g.level.resize(m);
  std::vector<double> nulls;
  double total_nulls = 0;
  for (size_t k = 0; k < m; ++k) {
    const auto& r = d.dwells[k];
    // Union-find roots: a parent always has the lower index, so a set's root (its lowest index)
    // comes first and has its level when the others look it up.
    uint32_t root = static_cast<uint32_t>(k);
    while (d.dwells[root].link != root) root = d.dwells[root].link;
    if (root == k) {
      g.level[k] = static_cast<uint32_t>(g.levels++);
      nulls.push_back(0);
    } else {
      g.level[k] = g.level[root];
    }
    if (r.null()) {
      nulls[g.level[k]] += 1;
      total_nulls += 1;
    }
  }
  if (g.levels == 1) std::vector<uint32_t>().swap(g.level);  // the usual one level: no list (memory)
  g.counts.resize(m);
  g.var_counts2.resize(m);
  g.var_sensor_counts2.resize(m);
  for (size_t k = 0; k < m; ++k) {
    const auto& r = d.dwells[k];
    const double n = static_cast<double>(std::max<uint32_t>(1, r.samples()));
    // vc is the count estimate's variance; vs its sensor-noise part, the rest being the rounding's
    // (the uncertainty budget's split, to first order).
    double c = r.counts, vc = 0, vs = 0;
    if (ni.quantisation_corrected) {
      c = counts_from_rounded_mean(r.counts, *s);
      const double h = expected_rounded_slope(c, *s);
      vc = rounded_counts_variance(c, *s) / (n * h * h);
      vs = *s * *s / (n * h * h);
    } else if (s && whole && *s < kMinQuantisationNoise) {
      vc = 1.0 / 12.0;  // rounding without dither: an error of the dwell, not averaged away
    } else if (s && whole) {
      vc = rounded_counts_variance(r.counts, *s) / n;  // the raw mean's own scatter (no correction)
      vs = *s * *s / n;
    } else if (s) {
      vc = vs = *s * *s / n;
    }
    g.counts[k] = c;
    g.var_counts2[k] = static_cast<float>(vc);
    g.var_sensor_counts2[k] = static_cast<float>(std::min(vc, vs));
  }
  g.level_share.resize(g.levels);
  for (size_t l = 0; l < g.levels; ++l) g.level_share[l] = total_nulls > 0 ? nulls[l] / total_nulls : 0.0;
  return p;
}

}  // namespace

AxisFit fit_axis(const AxisData& d, const FrequencyGram& gram, Axis axis, const CalibrationOptions& opts) {
  AxisFit out;
  out.axis = axis_name(axis);
  out.coefficient_key = axis == Axis::alpha ? "alpha" : "beta";
  RefineOptions ro;
  ro.max_iterations = opts.max_iterations;
  ro.threads = opts.threads > 0 ? opts.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));

  struct Start {
    AxisCoeffs c;
    std::string label;
  };
  std::vector<Start> starts;
  const auto nodes = gram.best_nodes(opts.refine_nodes);
  for (const auto& n : nodes) {
    // A local minimum far above the best one is another basin's poor relative: frequency
    // quantisation costs a factor of a few at most, not orders of magnitude.
    if (n.cost > kKeepCostRatio * nodes.front().cost + 1e-12) continue;
    starts.push_back({gram.coefficients(n),
                      fmt::format("grid node w = ({:.2e}, {:.2e}) rad/count", gram.frequency(n.j), gram.frequency(n.k))});
  }
  if (opts.init) starts.push_back({axis == Axis::alpha ? opts.init->alpha : opts.init->beta, "start set (--init)"});
  if (starts.empty()) {
    throw DataError(fmt::format(
        "{} axis: no pair of grid frequencies gives a solvable linear problem: the data cannot separate "
        "the slope and the two sinusoids",
        out.axis));
  }
  out.solver.candidates = starts.size();
  out.solver.grid_rows = gram.rows();
  out.solver.grid_rms_arcsec =
      nodes.empty() ? std::nan("") : std::sqrt(nodes.front().cost / static_cast<double>(gram.rows()));

  const double fraction = std::min(1.0, static_cast<double>(opts.screen_max_rows) / static_cast<double>(d.rows()));
  // Screening: every start gets a bounded number of iterations; the winner then goes on.
  RefineOptions screen = ro;
  screen.max_iterations = std::min(ro.max_iterations, kScreenIterations);
  // Small problems are faster on one thread than paying for the pool.
  if (fraction >= 1.0 && d.rows() < kRowsPerThreadMin) screen.threads = ro.threads = 1;
  std::optional<Refined> best;
  std::string best_label;
  for (const auto& s : starts) {
    Refined r = refine_axis(d, s.c, screen, fraction);
    if (r.usable && (!best || r.final_cost < best->final_cost)) {
      best = std::move(r);
      best_label = s.label;
    }
  }
  if (!best) throw std::runtime_error(fmt::format("{} axis: the solver failed from every start", out.axis));
  // With the GLS to follow (over every dwell, in memory that does not grow with them), the changes'
  // least squares on the screening subset is start enough: no full-size Ceres problem.
  const bool gls = opts.gls && d.differences && !d.dwells.empty();
  Refined fin = (fraction >= 1.0 || gls) && best->converged ? std::move(*best) : refine_axis(d, best->coeffs, ro);
  if (!fin.usable) throw std::runtime_error(fmt::format("{} axis: the solver failed: {}", out.axis, fin.brief));

  out.coeffs = fin.coeffs;
  out.solver.start = best_label;
  out.solver.brief = fin.brief;
  out.solver.iterations = fin.iterations;
  out.solver.initial_cost = fin.initial_cost;
  out.solver.final_cost = fin.final_cost;
  out.solver.converged = fin.converged;

  Uncertainty u;
  if (gls) {
    Prepared pr = prepare_gls(d, opts);
    GlsFit gf = refine_gls(pr.g, out.coeffs, d.counts_lo, d.counts_hi, opts.remainder_sigmas);
    out.coeffs = gf.coeffs;
    out.fit_form = FitForm::gls;
    out.noise = pr.noise;
    out.reduced_chi2 = gf.reduced_chi2;
    out.chi2_dof = gf.dof;
    out.model_remainder = gf.model_remainder;
    out.sigma_scale = gf.sigma_scale;
    out.dwells_fitted = pr.g.size();
    out.levels = pr.g.levels;
    out.solver.gls_iterations = gf.iterations;
    out.solver.gls_converged = gf.converged;
    u = std::move(gf.uncertainty);
    out.temperature = u.temperature;
  } else {
    u = uncertainty(d, out.coeffs, ro);
  }
  out.sigma = u.sigma;
  out.angle_sigma_max_arcsec = u.angle_sigma_max_arcsec;  // the temperature's entry in it (refine_gls)
  out.covariance_pseudo_inverse = u.pseudo_inverse;
  out.covariance_note = u.note;

  out.residuals = residual_stats(d, out.coeffs);
  out.counts_range = {d.counts_lo, d.counts_hi};
  if (out.fit_form == FitForm::gls) {
    // The GLS minimises the dwells' standardised residuals, not the changes' sum of squares: the
    // costs reported are the changes' at the search's own origin (the nominal scale factor alone,
    // as the grid starts) and at the returned coefficients.
    double start = 0;
    for (size_t i = 0; i < d.rows(); ++i) {
      const double r = d.row_y_arcsec(i) - kNominalC2 * kArcsecPerRad * (d.row_n_plus(i) - d.row_n_minus(i));
      start += r * r;
    }
    out.solver.initial_cost = 0.5 * start;
    out.solver.final_cost = 0.5 * out.residuals.rms_arcsec * out.residuals.rms_arcsec * static_cast<double>(out.residuals.points);
  }
  out.covariance_sources = covariance_sources(out, u, d);
  list_angle_sigmas(out, u, d, opts.sigma_angles,
                    axis == Axis::alpha ? opts.sigma_range_pitch_arcsec : opts.sigma_range_yaw_arcsec);
  return out;
}

ResidualStats residual_stats(const AxisData& d, const AxisCoeffs& c) {
  ResidualStats st;
  st.points = d.rows();
  if (st.points == 0) return st;
  double sum = 0, sum_sq = 0;
  for (size_t i = 0; i < d.rows(); ++i) {
    const double a = std::abs(residual_arcsec(d, c, i));
    sum += a;
    sum_sq += a * a;
    st.max_abs_arcsec = std::max(st.max_abs_arcsec, a);
  }
  const double m = static_cast<double>(st.points);
  st.mean_abs_arcsec = sum / m;
  st.rms_arcsec = std::sqrt(sum_sq / m);
  st.sd_arcsec = st.points > 1 ? std::sqrt(std::max(0.0, (sum_sq - m * st.mean_abs_arcsec * st.mean_abs_arcsec) / (m - 1))) : 0.0;
  st.range_deg = {d.ref_lo_arcsec / kArcsecPerDeg, d.ref_hi_arcsec / kArcsecPerDeg};
  return st;
}

std::vector<DwellPair> add_dwell_rows(AxisData& alpha, AxisData& beta, const std::vector<Dwell>& dwells) {
  std::vector<DwellPair> pairs;
  if (alpha.differences) {
    // In recording order, as the streaming calibrator takes them: the changes each dwell completes
    // (the rows come in pair_dwells' order), then the dwell's null condition.
    DwellPairer pairer;
    for (const auto& d : dwells) {
      for (const auto& p : pairer.add(d)) {
        add_pair_rows(alpha, Axis::alpha, dwells[p.null_index], dwells[p.offset_index]);
        add_pair_rows(beta, Axis::beta, dwells[p.null_index], dwells[p.offset_index]);
        pairs.push_back(p);
      }
      if (d.phase != Phase::null) continue;
      add_null(alpha, Axis::alpha, d);
      add_null(beta, Axis::beta, d);
    }
  } else {
    for (const auto& d : dwells) {
      add_absolute_row(alpha, Axis::alpha, d);
      add_absolute_row(beta, Axis::beta, d);
    }
  }
  return pairs;
}

}  // namespace fit

CalibrationReport calibrate_dwells(const std::vector<Dwell>& dwells, const CalibrationOptions& opts,
                                   const std::string& source, size_t samples) {
  const std::string src = source.empty() ? "samples" : source;
  CalibrationReport rep;
  rep.method = opts.method;
  rep.source = source;
  rep.unit = opts.unit;
  rep.samples = samples;
  rep.outliers.applied = opts.reject_outliers;
  for (const auto& d : dwells) {
    (d.phase == Phase::null ? rep.null_dwells : rep.offset_dwells)++;
    rep.outliers.add(d);
  }
  if (dwells.empty()) {
    throw DataError(fmt::format("{}: no null or offset rows: nothing to calibrate (slew and move rows are not used)", src));
  }
  if (rep.offset_dwells == 0) {
    throw DataError(fmt::format("{}: no offset dwells ({} null dwells): the transfer function cannot be told "
                                "from the null alone", src, rep.null_dwells));
  }
  const bool diff = opts.method == Method::differences;
  fit::AxisData a, b;
  a.differences = b.differences = diff;
  if (diff && rep.null_dwells == 0) {
    throw DataError(fmt::format(
        "{}: no null dwells: the differences method measures every offset against a neighbouring null "
        "dwell and fixes C1 by the null condition (record null dwells between offsets, or use "
        "--method absolute)",
        src));
  }
  rep.pairs = fit::add_dwell_rows(a, b, dwells).size();
  fit::check_axis(a, fit::Axis::alpha, source);
  fit::check_axis(b, fit::Axis::beta, source);

  auto fit_one = [&](const fit::AxisData& d, fit::Axis axis) {
    fit::FrequencyGram gram(opts.grid, diff);
    const double fraction = std::min(1.0, static_cast<double>(opts.grid_max_rows) / static_cast<double>(d.rows()));
    for (size_t i = 0; i < d.rows(); ++i) {
      if (fit::in_spread_subset(i, fraction)) gram.add(d.row_n_plus(i), d.row_n_minus(i), d.row_y_arcsec(i));
    }
    return fit::fit_axis(d, gram, axis, opts);
  };
  rep.pitch = fit_one(a, fit::Axis::alpha);
  rep.yaw = fit_one(b, fit::Axis::beta);
  if (rep.unit.empty() && opts.init) rep.unit = opts.init->unit;
  add_reference_uncertainty(rep, opts);
  return rep;
}

CalibrationReport calibrate(const Reduction& reduced, const CalibrationOptions& opts, const std::string& source,
                            size_t samples) {
  CalibrationReport rep = calibrate_dwells(reduced.dwells, opts, source, samples);
  rep.outliers = reduced.outliers;
  return rep;
}

CalibrationReport calibrate(const SampleTable& samples, const CalibrationOptions& opts) {
  if (opts.reference && opts.correct_reference) {
    const SampleTable corrected = with_reference_applied(samples, opts);
    return calibrate(reduce(corrected, opts.reduction()), opts, samples.origin, samples.size());
  }
  return calibrate(reduce(samples, opts.reduction()), opts, samples.origin, samples.size());
}

std::optional<size_t> AxisFit::worst_budget_angle() const {
  std::optional<size_t> worst;
  double worst_u = -1;
  for (size_t i = 0; i < angle_budget.size(); ++i) {
    if (angle_budget[i].empty()) continue;
    if (const double big_u = combine(angle_budget[i]).U; big_u > worst_u) {
      worst_u = big_u;
      worst = i;
    }
  }
  return worst;
}

double AxisFit::listed_sigma_max_arcsec() const {
  if (angle_sigma_arcsec.empty()) return std::numeric_limits<double>::infinity();
  double worst = 0;
  for (const auto& [angle, sigma] : angle_sigma_arcsec) {
    if (!std::isfinite(sigma)) return std::numeric_limits<double>::infinity();
    worst = std::max(worst, sigma);
  }
  return worst;
}

}  // namespace fpss
