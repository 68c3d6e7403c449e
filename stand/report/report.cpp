#include "stand/report/report.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>

#include "base/clock.h"
#include "base/errors.h"
#include "base/text_file.h"
#include "calib/calibrator.h"
#include "calib/dwells.h"
#include "calib/outliers.h"
#include "calib/residuals.h"
#include "calib/units.h"
#include "stand/report/budget_section.h"
#include "stand/report/plot.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;

// A reference change below this is an axis standing still (the other axis's offset).
constexpr double kMovedArcsec = 1.0;

// Table 1's figures of one axis's rows, computed by the calibrator's own code (none without rows).
AxisResidualStats axis_stats(const fit::AxisData& d, const AxisCoeffs& c) {
  AxisResidualStats st;
  st.points = static_cast<int64_t>(d.rows());
  if (d.rows() == 0) return st;
  const ResidualStats r = fit::residual_stats(d, c);
  st.mean_abs_arcsec = r.mean_abs_arcsec;
  st.max_abs_arcsec = r.max_abs_arcsec;
  st.rms_arcsec = r.rms_arcsec;
  st.sd_arcsec = r.sd_arcsec;
  if (d.covered) {
    st.range_lo_deg = r.range_deg[0];
    st.range_hi_deg = r.range_deg[1];
  }
  return st;
}

std::string num(double v, int decimals) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, decimals) : std::string("&ndash;");
}

std::string opt(const std::optional<double>& v, int decimals) {
  return v ? num(*v, decimals) : std::string("&ndash;");
}

const char* kStyle = R"css(
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; line-height: 1.4; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; }
h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; padding-bottom: 0.2em; margin-top: 1.6em; }
.sub { color: #555; }
table { border-collapse: collapse; margin: 0.6em 0; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; vertical-align: top; }
th { background: #f3f3f3; }
td.l, th.l { text-align: left; }
.note { background: #fff7e0; border-left: 4px solid #e0a800; padding: 0.4em 0.8em; }
.missing { background: #fdecea; border-left: 4px solid #c0392b; padding: 0.4em 0.8em; }
.plot { max-width: 100%; margin: 0.5em 0; }
.plot svg { width: 100%; height: auto; }
.plots2 { display: grid; grid-template-columns: 1fr 1fr; gap: 1em; }
pre { background: #f7f7f7; padding: 0.6em; overflow-x: auto; font-size: 0.85em; }
code { font-size: 0.9em; }
footer { margin-top: 2em; color: #777; font-size: 0.85em; }
)css";

// Flattens run.json into rows "key" / "key.sub" (two levels); long texts (procedure and stand
// files) and lists (sessions) go in folded blocks.
void flatten_run(const std::string& key, const nlohmann::json& v, int depth, std::string& rows,
                 std::string& blocks) {
  if (v.is_object() && depth < 2 && !v.empty()) {
    for (auto it = v.begin(); it != v.end(); ++it) {
      flatten_run(key.empty() ? it.key() : key + "." + it.key(), it.value(), depth + 1, rows, blocks);
    }
    return;
  }
  if (v.is_null() || (v.is_string() && v.get<std::string>().empty())) return;
  const std::string text = v.is_string() ? v.get<std::string>() : v.dump(1);
  if (text.size() > 160 || text.find('\n') != std::string::npos) {
    blocks += fmt::format("<details><summary><code>{}</code></summary><pre>{}</pre></details>\n",
                          html_escape(key), html_escape(text));
  } else {
    rows += fmt::format("<tr><th class=\"l\">{}</th><td class=\"l\">{}</td></tr>\n", html_escape(key),
                        html_escape(text));
  }
}

void run_section(std::string& h, const std::optional<RunFile>& run) {
  h += "<section id=\"run\"><h2>Run</h2>\n";
  if (!run) {
    h += "<p class=\"note\">No run.json in this folder: the run's settings are not known.</p></section>\n";
    return;
  }
  std::string rows, blocks;
  flatten_run("", to_json(*run), 0, rows, blocks);
  h += "<table>\n" + rows + "</table>\n" + blocks + "</section>\n";
}

// Why a grid took fewer points than planned (run.json `adaptive_stops`).
void adaptive_stop_note(std::string& h, const std::optional<RunFile>& run) {
  if (!run || !run->adaptive_stops) return;
  for (const auto& st : *run->adaptive_stops) {
    const double nan = std::nan("");
    h += fmt::format("<p class=\"note\">Adaptive stop, step {} ({}): the live fit's largest 1-sigma over the grid's "
                     "range was {} arcsec, at most the target {} arcsec, so {} of its points were not measured "
                     "(from point {}).</p>\n",
                     num(static_cast<double>(st.step), 0), html_escape(st.axes), num(st.sigma_max_arcsec.value_or(nan), 4),
                     num(st.until_sigma_arcsec, 4), num(static_cast<double>(st.points_skipped), 0),
                     num(st.first_skipped_point ? static_cast<double>(*st.first_skipped_point) : nan, 0));
  }
}

// The outlier frames beside Table 1: a unit that sends glitch frames is a finding, not noise.
void outliers_note(std::string& h, const OutlierSummary& o) {
  if (!o.applied) {
    h += "<p id=\"outliers\">Outlier frames: the rule was off; every frame is in the dwell means.</p>\n";
    return;
  }
  h += fmt::format(
      "<p id=\"outliers\" class=\"{}\">Outlier frames: {} of {} dwell frames ({:.2f} %) lie more than {} robust "
      "sigmas from their step and are left out of the dwell means: pitch (alpha) {} ({:.2f} %), yaw (beta) {} "
      "({:.2f} %).{}</p>\n",
      o.any.outlier_frames > 0 ? "note" : "sub", o.any.outlier_frames, o.frames, 100 * o.any.share(o.frames),
      OutlierRule{}.threshold_sigma, o.alpha.outlier_frames, 100 * o.alpha.share(o.frames), o.beta.outlier_frames,
      100 * o.beta.share(o.frames),
      o.any.outlier_frames > 0 ? " Frames far off with a valid CRC are the unit's own glitches (or a disturbed bench), "
                                 "not its noise: they are counted, not averaged in."
                               : "");
}

// Table 1 of the paper: per axis mean |residual| +- sd, max |residual|, points, range.
void summary_section(std::string& h, const ReportInput& in) {
  const auto& r = in.residuals;
  h += "<section id=\"summary\"><h2>Calibration summary (Table 1 form)</h2>\n";
  h += fmt::format(
      "<p>Residuals of the calibration <code>{}</code> on the recording <code>{}</code> ({} samples; {} null "
      "and {} offset dwells; method: {}). {}</p>\n",
      html_escape(in.calibration_origin), html_escape(in.samples_origin), in.samples, r.null_dwells,
      r.offset_dwells, html_escape(r.method),
      r.method == "differences"
          ? "Each residual is the model's change of angle minus the reference's change between an offset "
            "dwell and a neighbouring null dwell, for every change null&nbsp;&rarr;&nbsp;offset and "
            "offset&nbsp;&rarr;&nbsp;null (the paper's method)."
          : "Each residual is the model's angle minus the reference angle of one dwell.");
  adaptive_stop_note(h, in.run);
  if (in.fit_last_step) {
    h += fmt::format("<p>The rows the calibration was fitted on: steps 1 to {}. Points measured after the calibrate "
                     "step (verification, rest dwells) are not in this table.</p>\n", *in.fit_last_step);
  }
  // Table 1 is the calibrator's (calibration.json's residuals block): computed once, shown here.
  // The residuals recomputed on this recording feed the plots; a block that disagrees with them
  // points at a calibration made on other data.
  const auto& extra = in.calibration.extra;
  AxisResidualStats shown[2] = {r.pitch, r.yaw};
  std::string diffs;
  const bool has_block = extra.contains("residuals") && extra["residuals"].is_object();
  for (int ax = 0; ax < 2 && has_block; ++ax) {
    const char* name = ax == 0 ? "pitch" : "yaw";
    const AxisResidualStats& here = ax == 0 ? r.pitch : r.yaw;
    if (!extra["residuals"].contains(name)) continue;
    try {
      const auto c = AxisResidualStats::from_json(extra["residuals"][name], "calibration.json");
      shown[ax] = c;
      const bool same_points = !c.points || c.points == here.points;
      const bool same_mean = !c.mean_abs_arcsec || !here.mean_abs_arcsec ||
                             std::abs(*c.mean_abs_arcsec - *here.mean_abs_arcsec) <= 1e-6 + 1e-6 * *c.mean_abs_arcsec;
      if (!same_points || !same_mean) {
        diffs += fmt::format(" {}: {} points, mean {} arcsec here;", name, here.points.value_or(0),
                             opt(here.mean_abs_arcsec, 3));
      }
    } catch (const InputError&) {
      diffs += fmt::format(" {}: unreadable;", name);
    }
  }
  h += "<table>\n<tr><th class=\"l\">axis</th><th class=\"l\">from</th><th>range (deg)</th>"
       "<th>mean |residual| &plusmn; sd (arcsec)</th><th>max |residual| (arcsec)</th><th>rms (arcsec)</th>"
       "<th>points</th></tr>\n";
  for (const auto& [name, key, st] : {std::tuple{"pitch", "alpha, counts_alpha", &shown[0]},
                                      std::tuple{"yaw", "beta, counts_beta", &shown[1]}}) {
    const std::string range = st->range_lo_deg && st->range_hi_deg
                                  ? fmt::format("{:+.2f} to {:+.2f}", *st->range_lo_deg, *st->range_hi_deg)
                                  : std::string("&ndash;");
    h += fmt::format(
        "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{} &plusmn; {}</td><td>{}</td>"
        "<td>{}</td><td>{}</td></tr>\n",
        name, key, range, opt(st->mean_abs_arcsec, 2), opt(st->sd_arcsec, 2), opt(st->max_abs_arcsec, 2),
        opt(st->rms_arcsec, 2), st->points.value_or(0));
  }
  h += "</table>\n";
  outliers_note(h, r.outliers);
  if (r.points.empty()) {
    h += "<p class=\"missing\">The recording has no null/offset changes to measure residuals on "
         "(slews and moves are not used).</p>\n";
  }
  if (!diffs.empty()) {
    h += fmt::format("<p class=\"note\">The residuals block of calibration.json (shown above) differs from the "
                     "residuals recomputed here on this recording:{} was the calibration made on other data?</p>\n",
                     html_escape(diffs));
  }
  h += "</section>\n";
}

void coefficients_section(std::string& h, const ReportInput& in) {
  const auto& c = in.calibration;
  const auto& extra = c.extra;
  auto sigma = [&](const char* key, size_t i) -> std::string {
    if (!extra.contains("uncertainties") || !extra["uncertainties"].is_object()) return "&ndash;";
    const auto& u = extra["uncertainties"];
    if (!u.contains(key) || !u[key].is_array() || u[key].size() != 8 || !u[key][i].is_number()) return "&ndash;";
    return fmt::format("{:.2e}", u[key][i].get<double>());
  };
  h += "<section id=\"coefficients\"><h2>Coefficients</h2>\n";
  h += "<p>angle = C1 + C2&nbsp;N + C3&nbsp;sin(C4&nbsp;N + C5) + C6&nbsp;sin(C7&nbsp;N + C8), radians, N in "
       "counts (paper eq. 1, 2); &sigma; is the fit's 1-sigma where the calibrator gives it.</p>\n";
  h += "<table>\n<tr><th></th><th>alpha (pitch)</th><th>&sigma;</th><th>beta (yaw)</th><th>&sigma;</th></tr>\n";
  for (size_t i = 0; i < 8; ++i) {
    h += fmt::format("<tr><th>C{}</th><td>{:.7e}</td><td>{}</td><td>{:.7e}</td><td>{}</td></tr>\n", i + 1,
                     c.alpha[i], sigma("alpha", i), c.beta[i], sigma("beta", i));
  }
  h += "</table>\n";
  std::string rows;
  for (auto it = extra.begin(); it != extra.end(); ++it) {
    if (!it.value().is_primitive() || it.value().is_null()) continue;  // blocks are shown elsewhere
    const std::string v = it.value().is_string() ? it.value().get<std::string>() : it.value().dump();
    rows += fmt::format("<tr><th class=\"l\">{}</th><td class=\"l\">{}</td></tr>\n", html_escape(it.key()),
                        html_escape(v));
  }
  if (!c.unit.empty()) rows = fmt::format("<tr><th class=\"l\">unit</th><td class=\"l\">{}</td></tr>\n", html_escape(c.unit)) + rows;
  if (!rows.empty()) h += "<table>\n" + rows + "</table>\n";
  h += "</section>\n";
}

struct Plots {
  Gnuplot gp;
  std::optional<std::string> missing;  // set once gnuplot cannot be started: no further tries
  int next_id = 0;

  std::string draw(const std::string& script, const std::string& what, int w, int hgt) {
    if (missing) return {};
    const auto r = gp.svg(script, fmt::format("p{}_", ++next_id), w, hgt);
    if (r.svg) return "<div class=\"plot\">" + *r.svg + "</div>\n";
    if (r.program_missing) {
      missing = r.error;
      return {};
    }
    return fmt::format("<p class=\"missing\">Plot missing ({}): {}</p>\n", html_escape(what), html_escape(r.error));
  }
};

// The calibration's [angle_arcsec, sigma_arcsec] list of one axis (calibration.json
// `uncertainties.<axis>.angle_sigma_arcsec`); empty when absent or not of that shape.
std::vector<std::array<double, 2>> sigma_curve(const CoefficientSet& cal, const char* axis) {
  std::vector<std::array<double, 2>> out;
  const auto& x = cal.extra;
  if (!x.contains("uncertainties") || !x["uncertainties"].is_object()) return out;
  const auto& u = x["uncertainties"];
  if (!u.contains(axis) || !u[axis].is_object() || !u[axis].contains("angle_sigma_arcsec")) return out;
  const auto& list = u[axis]["angle_sigma_arcsec"];
  if (!list.is_array() || list.size() > 10000) return out;
  for (const auto& e : list) {
    if (!e.is_array() || e.size() != 2 || !e[0].is_number() || !e[1].is_number()) continue;  // null: not reached
    out.push_back({e[0].get<double>(), e[1].get<double>()});
  }
  return out;
}

std::string angle_plot_script(const RunResiduals& r, bool pitch, const std::vector<std::array<double, 2>>& sigma) {
  std::vector<std::vector<double>> fwd, back, still;
  for (const auto& p : r.points) {
    const double deg = (pitch ? p.ref_pitch_arcsec : p.ref_yaw_arcsec) / kArcsecPerDeg;
    const double res = pitch ? p.pitch_arcsec : p.yaw_arcsec;
    if (!(pitch ? p.pitch_moved : p.yaw_moved)) still.push_back({deg, res});
    else (p.null_first ? fwd : back).push_back({deg, res});
  }
  const char* axis = pitch ? "pitch" : "yaw";
  std::string s;
  s += fmt::format("set title '{} residuals against {} angle'\n", pitch ? "Pitch" : "Yaw", axis);
  s += fmt::format("set xlabel '{} reference angle (deg)'\n", axis);
  s += r.method == "differences" ? "set ylabel 'residual, offset minus null (arcsec)'\n"
                                 : "set ylabel 'residual (arcsec)'\n";
  s += "set grid\nset key top left box opaque\nset xzeroaxis lt -1 lc rgb '#888888'\n";
  std::vector<std::string> parts;
  if (!still.empty()) {
    s += datablock("still", still);
    parts.push_back(fmt::format("$still using 1:2 with points pt 1 ps 0.6 lc rgb '#aaaaaa' title '{} still "
                                "(offset along {})'", axis, pitch ? "yaw" : "pitch"));
  }
  if (!fwd.empty()) {
    s += datablock("fwd", fwd);
    parts.push_back(fmt::format("$fwd using 1:2 with points pt 7 ps 0.7 lc rgb '#1f77b4' title '{}'",
                                r.method == "differences" ? "from the null before" : "dwell"));
  }
  if (!back.empty()) {
    s += datablock("back", back);
    parts.push_back("$back using 1:2 with points pt 6 ps 0.9 lc rgb '#d62728' title 'from the null after'");
  }
  if (!sigma.empty()) {
    std::vector<std::vector<double>> band;
    for (const auto& [angle, sig] : sigma) band.push_back({angle / kArcsecPerDeg, sig, -sig});
    s += datablock("sig", band);
    parts.push_back("$sig using 1:2 with lines lw 2 lc rgb '#2ca02c' title 'calibration 1-sigma (+-)'");
    parts.push_back("$sig using 1:3 with lines lw 2 lc rgb '#2ca02c' notitle");
  }
  s += "plot ";
  for (size_t i = 0; i < parts.size(); ++i) s += (i ? ", " : "") + parts[i];
  return s + "\n";
}

// One vector per offset position: the mean of its changes' residuals (against the null before
// and the null after). Returns the script and the arrow scale (deg of field per arcsec of residual).
std::pair<std::string, double> map_plot_script(const RunResiduals& r) {
  struct Acc {
    double yaw = 0, pitch = 0, ry = 0, rp = 0;
    int n = 0;
  };
  std::map<int64_t, Acc> by_step;
  for (const auto& p : r.points) {
    auto& a = by_step[p.step];
    a.yaw += p.ref_yaw_arcsec;
    a.pitch += p.ref_pitch_arcsec;
    a.ry += p.yaw_arcsec;
    a.rp += p.pitch_arcsec;
    ++a.n;
  }
  double max_mag = 0;
  for (const auto& [step, a] : by_step) {
    max_mag = std::max(max_mag, std::hypot(a.ry / a.n, a.rp / a.n));
  }
  double lo_y = 0, hi_y = 0, lo_p = 0, hi_p = 0;
  for (const auto& [step, a] : by_step) {
    lo_y = std::min(lo_y, a.yaw / a.n / kArcsecPerDeg); hi_y = std::max(hi_y, a.yaw / a.n / kArcsecPerDeg);
    lo_p = std::min(lo_p, a.pitch / a.n / kArcsecPerDeg); hi_p = std::max(hi_p, a.pitch / a.n / kArcsecPerDeg);
  }
  // The longest arrow spans a tenth of the field covered (at least 0.01 deg of field).
  const double field = std::max({hi_y - lo_y, hi_p - lo_p, 0.1});
  const double scale_deg_per_arcsec = max_mag > 0 ? 0.1 * field / max_mag : 0.0;
  std::vector<std::vector<double>> rows;
  for (const auto& [step, a] : by_step) {
    const double ry = a.ry / a.n, rp = a.rp / a.n;
    rows.push_back({a.yaw / a.n / kArcsecPerDeg, a.pitch / a.n / kArcsecPerDeg, ry * scale_deg_per_arcsec,
                    rp * scale_deg_per_arcsec, std::hypot(ry, rp)});
  }
  const double pad = 0.15 * field;
  std::string s;
  s += "set title 'Residual map over the field'\n";
  s += "set xlabel 'yaw reference angle (deg)'\nset ylabel 'pitch reference angle (deg)'\n";
  s += fmt::format("set xrange [{:.6f}:{:.6f}]\nset yrange [{:.6f}:{:.6f}]\n", lo_y - pad, hi_y + pad, lo_p - pad,
                   hi_p + pad);
  s += "set size ratio -1\nset grid\nunset key\n";
  s += "set cblabel '|residual| (arcsec)'\n";
  s += "set palette defined (0 '#2c7bb6', 0.5 '#fdae61', 1 '#d7191c')\n";
  s += fmt::format("set cbrange [0:{:.6g}]\n", std::max(max_mag, 1e-3));
  s += datablock("vec", rows);
  s += "plot $vec using 1:2:5 with points pt 7 ps 0.9 lc palette, "
       "$vec using 1:2:3:4:5 with vectors head filled size screen 0.008,25 lw 1.5 lc palette\n";
  return {s, scale_deg_per_arcsec};
}

void plots_section(std::string& h, const ReportInput& in, const ReportOptions& opts) {
  const auto& r = in.residuals;
  h += "<section id=\"plots\"><h2>Residuals against angle</h2>\n";
  if (r.points.empty()) {
    h += "<p class=\"missing\">No residuals to plot.</p></section>\n";
    return;
  }
  Plots plots{Gnuplot(opts.gnuplot), std::nullopt, 0};
  std::string angle = plots.draw(angle_plot_script(r, true, sigma_curve(in.calibration, "pitch")),
                                 "pitch residuals against angle", 640, 420);
  angle += plots.draw(angle_plot_script(r, false, sigma_curve(in.calibration, "yaw")), "yaw residuals against angle",
                      640, 420);
  const auto [map_script, scale] = map_plot_script(r);
  std::string map = plots.draw(map_script, "residual map", 720, 640);
  if (plots.missing) {
    const std::string note = fmt::format("<p class=\"missing\">The plots are missing: {}. The tables above and "
                                         "the residual table below are complete.</p>\n",
                                         html_escape(*plots.missing));
    h += note + "<h2 id=\"map\">Residual map over the field</h2>\n" + note + "</section>\n";
    return;
  }
  if (r.method == "differences") {
    h += "<p>Each offset is measured against the null dwell before it and the one after it; both residuals are "
         "taken offset minus null, so both show the model's error at the offset. Grey: offsets along the other "
         "axis, where this axis stood still.</p>\n";
  }
  h += "<p>Green: &plusmn; the calibration's 1-sigma of the fitted angle over the calibrated range (the null "
       "condition included; calibration.json <code>uncertainties</code>). The residuals scatter with the "
       "measurement noise of each change; the curve is how far the fitted transfer function itself may be "
       "off.</p>\n";
  h += "<div class=\"plots2\">" + angle + "</div>\n";
  h += "<h2 id=\"map\">Residual map over the field</h2>\n";
  h += fmt::format("<p>At each offset position the arrow is the residual vector (yaw, pitch), the mean of the "
                   "changes measured there; its colour is the vector's length. Arrow scale: "
                   "1 arcsec of residual is drawn as {:.3g} deg of field.</p>\n",
                   scale);
  h += map + "</section>\n";
}

void points_section(std::string& h, const RunResiduals& r) {
  if (r.points.empty()) return;
  h += "<section id=\"points\"><h2>Residual table</h2>\n<details><summary>";
  h += fmt::format("All {} {}</summary>\n", r.points.size(),
                   r.method == "differences" ? "changes" : "dwells");
  h += "<table>\n<tr><th>step</th><th class=\"l\">against</th><th>ref pitch (arcsec)</th><th>ref yaw (arcsec)</th>"
       "<th>pitch residual (arcsec)</th><th>yaw residual (arcsec)</th></tr>\n";
  for (const auto& p : r.points) {
    h += fmt::format("<tr><td>{}</td><td class=\"l\">{}</td><td>{:.2f}</td><td>{:.2f}</td><td>{:.3f}</td>"
                     "<td>{:.3f}</td></tr>\n",
                     p.step, p.absolute ? "dwell" : (p.null_first ? "null before" : "null after"),
                     p.ref_pitch_arcsec, p.ref_yaw_arcsec, p.pitch_arcsec, p.yaw_arcsec);
  }
  h += "</table>\n</details>\n</section>\n";
}

}  // namespace

std::string html_escape(const std::string& text) {
  std::string o;
  o.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      case '\'': o += "&#39;"; break;
      default: o += c;
    }
  }
  return o;
}

RunResiduals compute_residuals(const SampleTable& samples, const CoefficientSet& cal, const std::string& method) {
  return compute_residuals(reduce(samples, reduction_options_of(cal.extra, "calibration.json")), cal, method);
}

RunResiduals compute_residuals(const Reduction& reduced, const CoefficientSet& cal, const std::string& method) {
  if (method != "differences" && method != "absolute") {
    throw InputError(fmt::format("unknown calibration method \"{}\" (expected differences or absolute)", method));
  }
  RunResiduals out;
  out.method = method;
  out.outliers = reduced.outliers;
  const std::vector<Dwell>& dwells = reduced.dwells;
  for (const auto& d : dwells) (d.phase == Phase::null ? out.null_dwells : out.offset_dwells)++;
  fit::AxisData a, b;
  a.differences = b.differences = method == "differences";
  const std::vector<DwellPair> pairs = fit::add_dwell_rows(a, b, dwells);
  if (a.differences) {
    for (const auto& p : pairs) {
      const Dwell& null_dwell = dwells[p.null_index];
      const Dwell& off = dwells[p.offset_index];
      ResidualPoint pt;
      pt.step = off.step;
      pt.null_first = p.null_first;
      pt.ref_pitch_arcsec = off.ref_pitch_arcsec;
      pt.ref_yaw_arcsec = off.ref_yaw_arcsec;
      pt.pitch_moved = std::abs(off.ref_pitch_arcsec - null_dwell.ref_pitch_arcsec) > kMovedArcsec;
      pt.yaw_moved = std::abs(off.ref_yaw_arcsec - null_dwell.ref_yaw_arcsec) > kMovedArcsec;
      out.points.push_back(pt);
    }
  } else {
    for (const auto& d : dwells) {
      ResidualPoint pt;
      pt.step = d.step;
      pt.absolute = true;
      pt.ref_pitch_arcsec = d.ref_pitch_arcsec;
      pt.ref_yaw_arcsec = d.ref_yaw_arcsec;
      out.points.push_back(pt);
    }
  }
  for (size_t i = 0; i < out.points.size(); ++i) {
    out.points[i].pitch_arcsec = fit::residual_arcsec(a, cal.alpha, i);
    out.points[i].yaw_arcsec = fit::residual_arcsec(b, cal.beta, i);
  }
  out.pitch = axis_stats(a, cal.alpha);
  out.yaw = axis_stats(b, cal.beta);
  return out;
}

ReportInput load_report_input(const fs::path& run_dir, const SampleTable* recording) {
  if (!fs::is_directory(run_dir)) throw InputError(fmt::format("{}: not a run folder (no such directory)", run_dir.string()));
  ReportInput in;
  const fs::path samples_path = run_dir / "samples.csv";
  const fs::path run_path = run_dir / "run.json";
  if (!recording && !fs::exists(samples_path)) {
    throw InputError(fmt::format("{}: missing: the run recorded no samples", samples_path.string()));
  }
  if (fs::exists(run_path)) in.run = read_run_file(run_dir);
  // A procedure may calibrate more than once (calibration-2.json, ...): run.json names the last.
  fs::path cal_path = run_dir / "calibration.json";
  if (in.run && in.run->files.calibration) {
    const fs::path named = *in.run->files.calibration;
    if (named.has_parent_path() || named.empty()) {
      throw InputError(fmt::format("{}: files.calibration must be a file name in the run folder, got \"{}\"",
                                   run_path.string(), named.string()));
    }
    cal_path = run_dir / named;
  }
  if (!fs::exists(cal_path)) {
    throw InputError(fmt::format("{}: missing: the run has no calibration to report on", cal_path.string()));
  }
  in.calibration = load_coefficients(cal_path);
  in.calibration_origin = cal_path.filename().string();
  std::string method = "differences";
  if (in.calibration.extra.contains("method")) {
    const auto& m = in.calibration.extra["method"];
    if (!m.is_string()) throw InputError(fmt::format("{}: \"method\" must be a string", cal_path.string()));
    method = m.get<std::string>();
    if (method != "differences" && method != "absolute") {
      throw InputError(fmt::format("{}: \"method\" is \"{}\", expected differences or absolute", cal_path.string(), method));
    }
  }
  SampleTable read;
  if (!recording) read = read_samples_csv(samples_path);
  const SampleTable& all = recording ? *recording : read;
  in.fit_last_step = fit_last_step(in.calibration, cal_path.string());
  SampleTable fitted;
  if (in.fit_last_step) fitted = all.up_to_step(*in.fit_last_step);
  const SampleTable& samples = in.fit_last_step ? fitted : all;
  in.samples_origin = samples_path.filename().string();
  in.samples = samples.size();
  in.residuals = compute_residuals(samples, in.calibration, method);

  std::string unit = in.run ? in.run->unit : std::string();
  if (unit.empty()) unit = in.calibration.unit;
  const std::string procedure = in.run ? in.run->procedure.name : std::string();
  in.title = fmt::format("Run {}{}{}", run_dir.filename().string(), unit.empty() ? "" : " \u2014 unit " + unit,
                         procedure.empty() ? "" : ", " + procedure);
  return in;
}

std::string render_report(const ReportInput& in, const ReportOptions& opts) {
  std::string h;
  h.reserve(256 * 1024);
  h += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  h += "<meta name=\"generator\" content=\"fpss-stand " FPSS_VERSION "\">\n";
  h += fmt::format("<title>{}</title>\n<style>{}</style>\n</head>\n<body>\n", html_escape(in.title), kStyle);
  h += fmt::format("<h1>{}</h1>\n<p class=\"sub\">Report written {} by fpss-stand {}. Angles in arcsec unless "
                   "marked deg; pitch from alpha (counts_alpha), yaw from beta (counts_beta).</p>\n",
                   html_escape(in.title), utc_now_iso(), FPSS_VERSION);
  h += verdict_banner_html(opts.verdict ? *opts.verdict : run_verdict(in.run));  // no run.json: incomplete
  h += "<nav><a href=\"#summary\">summary</a> &middot; <a href=\"#plots\">residuals against angle</a> &middot; "
       "<a href=\"#map\">residual map</a> &middot; <a href=\"#coefficients\">coefficients</a> &middot; "
       "<a href=\"#run\">run</a>";
  for (const auto& s : opts.extra_sections) {
    h += fmt::format(" &middot; <a href=\"#{}\">{}</a>", html_escape(s.id), html_escape(s.title));
  }
  h += "</nav>\n";
  summary_section(h, in);
  plots_section(h, in, opts);
  for (const auto& s : opts.extra_sections) {
    h += fmt::format("<section id=\"{}\"><h2>{}</h2>\n{}\n</section>\n", html_escape(s.id), html_escape(s.title), s.html);
  }
  coefficients_section(h, in);
  budget_section(h, in);
  run_section(h, in.run);
  points_section(h, in.residuals);
  h += "<footer>Self-contained page: no scripts, no external files. Plots drawn with gnuplot (svg terminal).</footer>\n";
  h += "</body>\n</html>\n";
  return h;
}

fs::path write_report(const fs::path& run_dir, const ReportOptions& opts) {
  const ReportInput in = load_report_input(run_dir, opts.recording);
  const fs::path out = run_dir / "report.html";
  write_text_atomic(out, render_report(in, opts));
  return out;
}

}  // namespace fpss
