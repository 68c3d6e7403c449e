#include "stand/report/diagnosis_page.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <sstream>

#include "base/text_file.h"
#include "stand/report/plot.h"
#include "stand/report/report.h"

namespace fpss {
namespace {

std::string esc(const std::string& s) { return html_escape(s); }

// One figure: pitch and yaw residual against a factor, before (grey) and after (blue).
std::string factor_script(const DiagnosisFactorSeries& f) {
  std::string s;
  for (int a = 0; a < 2; ++a) {
    std::vector<std::vector<double>> rows;
    for (size_t i = 0; i < f.x[a].size(); ++i) rows.push_back({f.x[a][i], f.before[a][i], f.after[a][i]});
    if (rows.empty()) rows.push_back({NAN, NAN, NAN});
    s += datablock(a == 0 ? "P" : "Y", rows);
  }
  s += "set termoption noenhanced\nset grid\nset key top right\nset multiplot layout 1,2\n";
  for (int a = 0; a < 2; ++a) {
    s += fmt::format("set title '{} residual vs {}'\nset xlabel '{}'\nset ylabel 'arcsec'\n", a == 0 ? "pitch" : "yaw",
                     gnuplot_quote(f.factor), gnuplot_quote(f.xlabel));
    s += fmt::format("plot ${0} using 1:2 with points pt 7 ps 0.3 lc rgb '#c0c0c0' title 'before', "
                     "${0} using 1:3 with points pt 7 ps 0.3 lc rgb '#1f5fbf' title 'after'\n",
                     a == 0 ? "P" : "Y");
  }
  return s + "unset multiplot\n";
}

// The residual map: one arrow per dwell, scaled by a power of ten so the largest is at most a
// tenth of the field (the same factor before and after).
std::string map_script(const std::vector<DiagnosisMapPoint>& map) {
  double field = 1, largest = 0;
  std::vector<std::vector<double>> rows;
  for (const auto& p : map) {
    field = std::max({field, std::abs(p.pitch_arcsec), std::abs(p.yaw_arcsec)});
    largest = std::max(largest, std::hypot(p.before[0], p.before[1]));
    rows.push_back({p.pitch_arcsec, p.yaw_arcsec, p.before[0], p.before[1], p.after[0], p.after[1]});
  }
  const double scale = largest > 0 ? std::pow(10.0, std::floor(std::log10(0.1 * field / largest))) : 1.0;
  std::string s = datablock("M", rows);
  s += "set termoption noenhanced\nset grid\nset size ratio -1\nset multiplot layout 1,2\n";
  for (int k = 0; k < 2; ++k) {
    s += fmt::format("set title 'dwell residuals over the field, {} (arrows x{:g})'\nset xlabel 'pitch, arcsec'\n"
                     "set ylabel 'yaw, arcsec'\n",
                     k == 0 ? "before" : "after", scale);
    s += fmt::format("plot $M using 1:2:({3:g}*${0}):({3:g}*${1}) with vectors head size 8,20 lc rgb '{2}' notitle, "
                     "$M using 1:2 with points pt 7 ps 0.3 lc rgb 'black' notitle\n",
                     k == 0 ? 3 : 5, k == 0 ? 4 : 6, k == 0 ? "#c03020" : "#1f5fbf", scale);
  }
  return s + "unset multiplot\n";
}

std::string limits_text(const EffectResult& e) {
  std::string s;
  for (auto it = e.detection_limit.begin(); it != e.detection_limit.end(); ++it) {
    s += fmt::format("{}{} {:.3g}", s.empty() ? "" : ", ", it.key(), it.value().get<double>());
  }
  return s;
}

}  // namespace

void write_diagnosis_page(const std::string& html_path, const Diagnosis& d, const DiagnosisFigures& figures) {
  std::ostringstream h;
  h << "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>Sim-to-real gap: " << esc(d.source)
    << "</title>\n<style>body{font-family:sans-serif;max-width:1000px;margin:1em auto}"
       "table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:2px 6px;text-align:left}"
       "th{background:#eee}.num{text-align:right}.verdict{font-size:1.2em}</style></head><body>\n";
  h << "<h1>Sim-to-real gap diagnosis</h1>\n";
  // The verdict in one plain sentence, then what this recording could and could not have seen.
  h << "<p class=verdict id=verdict><b>" << esc(d.verdict_sentence) << "</b></p>\n";
  h << "<h2 id=limits>What this recording could detect</h2>\n<p>The smallest magnitude of each effect that "
       "would have been material on these held-out steps (noise floor "
    << fmt::format("{:.4f}", d.noise_floor_arcsec) << " arcsec):</p>\n<table><tr><th>effect</th><th>detection limit</th></tr>\n";
  for (const auto& e : d.effects) {
    if (e.detection_limit.empty()) continue;
    h << "<tr><td>" << esc(e.name) << "</td><td>" << esc(limits_text(e)) << "</td></tr>\n";
  }
  h << "</table>\n";
  if (!d.not_observable.empty()) {
    h << "<p>Not observable in this recording:</p><ul>\n";
    for (const auto& n : d.not_observable) h << "<li><b>" << esc(n.name) << "</b>: " << esc(n.reason) << "</li>\n";
    h << "</ul>\n";
  }
  if (!d.ambiguous.empty()) {
    h << "<h2 id=ambiguous>What this recording cannot tell apart</h2>\n<table><tr><th>look-alikes</th><th>separated "
         "by</th><th>the run that would</th><th>best follow-up (predicted)</th></tr>\n";
    for (const auto& a : d.ambiguous) {
      std::string members;
      for (const auto& m : a.members) members += (members.empty() ? "" : " / ") + m;
      h << "<tr><td>" << esc(members) << "</td><td>" << esc(a.factor) << "</td><td>" << esc(a.measurement)
        << "</td><td><code>" << esc(a.best_followup.is_null() ? std::string("not designed") : a.best_followup.dump())
        << "</code></td></tr>\n";
    }
    h << "</table>\n";
  }
  h << "<p>Recording: <code>" << esc(d.source) << "</code></p>\n";
  h << "<table><tr><th>verdict</th><td>" << esc(d.verdict) << "</td></tr><tr><th>cause</th><td>" << esc(d.cause)
    << "</td></tr>";
  if (d.causes.size() > 1) {
    std::string cs;
    for (const auto& e : d.causes) cs += (cs.empty() ? "" : ", then ") + e.name;
    h << "<tr><th>causes</th><td>" << esc(cs) << "</td></tr>";
  }
  h << fmt::format("<tr><th>gap before (held-out RMS)</th><td class=num>{:.4f} arcsec</td></tr>", d.gap_before_arcsec);
  h << fmt::format("<tr><th>gap after the cause</th><td class=num>{:.4f} arcsec</td></tr>", d.gap_after_arcsec);
  if (d.causes.size() > 1) {
    h << fmt::format("<tr><th>gap after all causes</th><td class=num>{:.4f} arcsec</td></tr>", d.gap_after_all_arcsec);
  }
  h << fmt::format("<tr><th>noise floor</th><td class=num>{:.4f} arcsec</td></tr>", d.noise_floor_arcsec);
  if (std::isfinite(d.within_step_scatter_arcsec)) {
    h << fmt::format("<tr><th>within-step scatter</th><td class=num>{:.4f} arcsec</td></tr>", d.within_step_scatter_arcsec);
  }
  if (std::isfinite(d.expected_scatter_arcsec)) {
    h << fmt::format("<tr><th>expected scatter (model)</th><td class=num>{:.4f} arcsec ({:.2f}x measured)</td></tr>",
                     d.expected_scatter_arcsec, d.excess_scatter());
  }
  h << fmt::format("<tr><th>outlier frames</th><td class=num>{} ({:.2f} %): pitch {}, yaw {}</td></tr></table>\n",
                   d.outliers, 100 * d.outlier_fraction, d.outliers_pitch, d.outliers_yaw);
  for (const auto& e : d.causes) h << "<p><b>" << esc(e.name) << "</b>: <code>" << esc(e.params.dump()) << "</code></p>\n";

  auto where_table = [&](const char* title, const std::vector<WhereEntry>& w) {
    h << "<h2>" << title << "</h2>\n<table><tr><th>factor</th><th>axis</th><th>share</th><th>detail</th></tr>\n";
    for (const auto& e : w) {
      h << fmt::format("<tr><td>{}</td><td>{}</td><td class=num>{:.1f} %</td><td>{}</td></tr>\n", esc(e.factor),
                       esc(e.axis), 100 * e.share, esc(e.detail));
    }
    h << "</table>\n";
  };
  where_table("Where the gap lies (before)", d.where);
  where_table("What is left (after the causes)", d.where_after);
  if (d.unexplained) {
    where_table("The unexplained remainder", d.unexplained->where);
    h << "<p>A flexible, non-physical model of the leading factor(s): <code>"
      << esc(d.unexplained->flexible_shrink.dump()) << "</code></p>\n";
  }

  h << "<h2>Candidates (best first)</h2>\n<table><tr><th>effect</th><th>params</th><th>k</th><th>fit RMS</th>"
       "<th>held-out RMS</th><th>score</th><th>note</th></tr>\n";
  for (const auto& e : d.effects) {
    std::string params = e.params.dump();
    if (params.size() > 160) params = params.substr(0, 157) + "...";
    h << fmt::format("<tr><td>{}</td><td><code>{}</code></td><td class=num>{}</td><td class=num>{:.4f}</td>"
                     "<td class=num>{:.4f}</td><td class=num>{:.1f}</td><td>{}</td></tr>\n",
                     esc(e.name), esc(params), e.parameters, e.fit_rms_arcsec, e.heldout_rms_arcsec, e.score,
                     esc(e.degenerate.empty() ? "" : "degenerate: " + e.degenerate));
  }
  h << "</table>\n";
  h << "<h2>Split</h2>\n<pre>" << esc(d.split.dump(1)) << "</pre>\n";
  h << "<h2>Figures</h2>\n";
  const Gnuplot gp;
  std::string note;
  auto figure = [&](const std::string& title, const std::string& script, const std::string& id, int height) {
    if (!note.empty()) return;
    const PlotResult p = gp.svg(script, id, 900, height);
    if (!p.svg) {
      note = p.program_missing ? "gnuplot is not installed: figures left out (tables above)."
                               : "gnuplot failed (" + p.error + "): figures left out.";
      return;
    }
    h << "<h3>" << esc(title) << "</h3>\n" << *p.svg << "\n";
  };
  int k = 0;
  for (const auto& f : figures.factors) figure("Residual against " + f.factor, factor_script(f), fmt::format("f{}", k++), 360);
  if (!figures.map.empty()) figure("Residual map over the field (dwell means)", map_script(figures.map), "map", 420);
  if (!note.empty()) h << "<p>" << esc(note) << "</p>\n";
  h << "</body></html>\n";
  write_text_atomic(html_path, h.str());
}

}  // namespace fpss
