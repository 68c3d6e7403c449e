// The diagnosis's HTML report: figures by gnuplot (SVG, inlined) when it is installed, tables always.
#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "calib/text_file.h"
#include "calib/diagnosis.h"
#include "calib/diagnosis_model.h"
#include "calib/errors.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using diag::Contribution;
using diag::Recording;
using diag::StepKind;
using diag::Use;

std::string esc(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '&': o += "&amp;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

// The causes' contributions, rebuilt from their reported parameters.
Contribution contributions(const Recording& r, const std::vector<EffectResult>& causes) {
  Contribution sum, k;
  sum.resize(r.n);
  k.resize(r.n);
  for (const auto& c : causes) {
    auto cand = diag::make_candidate(c.name);
    if (!cand) continue;
    EffectParams p;
    p.name = c.name;
    if (c.name == "coefficients") {
      CoefficientSet set = r.model;
      set.alpha = c.params.at("alpha").get<AxisCoeffs>();
      set.beta = c.params.at("beta").get<AxisCoeffs>();
      p.coefficients = set;
    } else {
      for (auto it = c.params.begin(); it != c.params.end(); ++it) p.params[it.key()] = it.value().get<double>();
    }
    cand->set(p);
    cand->contribute(r, k);
    for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) sum.v[a][i] += k.v[a][i];
  }
  return sum;
}

bool have_gnuplot() {
  const char* path = std::getenv("PATH");
  if (!path) return false;
  std::stringstream ss(path);
  std::string dir;
  while (std::getline(ss, dir, ':')) {
    if (!dir.empty() && ::access((fs::path(dir) / "gnuplot").c_str(), X_OK) == 0) return true;
  }
  return false;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct Figure {
  std::string title, svg;
};

}  // namespace

void write_diagnosis_report(const std::string& html_path, const SampleTable& data, const CoefficientSet& model,
                            const Diagnosis& d, const DiagnosisOptions& opts) {
  const Recording r = diag::prepare(data, model, opts);
  const Contribution c = contributions(r, d.causes);
  std::vector<Figure> figures;
  std::string gnuplot_note;

  if (have_gnuplot()) {
    char tmpl[] = "/tmp/fpss-diagnosis-XXXXXX";
    if (!::mkdtemp(tmpl)) throw std::runtime_error("cannot create a temporary folder for the report's figures");
    const fs::path dir = tmpl;
    size_t moving_rows = 0, settle_rows = 0;
    {
      // Rows (at most ~20000, evenly strided) with every factor and both residuals.
      std::ofstream rows(dir / "rows.dat");
      const size_t stride = std::max<size_t>(1, r.n / 20000);
      rows << "# t ref_p ref_y vel_p vel_y dir_p dir_y since temp rp ry ap ay moving\n";
      for (size_t i = 0; i < r.n; i += stride) {
        if (r.use[i] == Use::excluded) continue;
        const bool moving = r.steps[r.step_of[i]].kind == StepKind::motion;
        if (moving) ++moving_rows;
        if (std::isfinite(r.since_move[i])) ++settle_rows;
        rows << fmt::format("{} {} {} {} {} {} {} {} {} {} {} {} {} {}\n", r.t[i], r.ref[0][i], r.ref[1][i],
                            moving ? r.vel[0][i] : 0.0, moving ? r.vel[1][i] : 0.0, static_cast<int>(r.dir[0][i]),
                            static_cast<int>(r.dir[1][i]), std::isfinite(r.since_move[i]) ? r.since_move[i] : -1.0,
                            std::isfinite(r.temp[i]) ? r.temp[i] : 0.0, r.res[0][i], r.res[1][i],
                            r.res[0][i] - c.v[0][i], r.res[1][i] - c.v[1][i], moving ? 1 : 0);
      }
      // Dwell means for the field map.
      std::ofstream dw(dir / "dwells.dat");
      for (const auto& s : r.steps) {
        if (s.kind != StepKind::dwell) continue;
        double m[6] = {0, 0, 0, 0, 0, 0};
        for (size_t i = s.begin; i < s.end; ++i) {
          m[0] += r.ref[0][i]; m[1] += r.ref[1][i];
          m[2] += r.res[0][i]; m[3] += r.res[1][i];
          m[4] += r.res[0][i] - c.v[0][i]; m[5] += r.res[1][i] - c.v[1][i];
        }
        const double k = 1.0 / static_cast<double>(s.end - s.begin);
        dw << fmt::format("{} {} {} {} {} {}\n", m[0] * k, m[1] * k, m[2] * k, m[3] * k, m[4] * k, m[5] * k);
      }
    }
    struct Spec { std::string name, xlabel; int col_p, col_y; std::string cond; };
    std::vector<Spec> specs = {
        {"angle", "own axis angle, arcsec", 2, 3, ""},
        {"cross_angle", "other axis angle, arcsec", 3, 2, ""},
        {"approach_direction", "direction of the last motion of the axis", 6, 7, ""},
        {"time", "time, s", 1, 1, ""},
    };
    // Factors with nothing to show (no slews, no dwells after moves) are left out: gnuplot
    // stops at an empty plot.
    if (moving_rows > 0) specs.insert(specs.begin() + 2, {"slew_rate", "own axis rate, arcsec/s (slews)", 4, 5, "moving"});
    if (settle_rows > 0) specs.push_back({"time_since_move", "time since the move ended, s (dwells)", 8, 8, "since"});
    if (r.has_temperature) specs.push_back({"temperature", "temperature, C", 9, 9, ""});
    std::ofstream gp(dir / "plots.gp");
    gp << "set terminal svg size 900,360 font 'sans,10' background rgb 'white'\nset termoption noenhanced\n"
          "set grid\nset key top right\n";
    for (const auto& s : specs) {
      auto x = [&](int col) {
        if (s.cond == "since") return fmt::format("(${} >= 0 ? ${} : 1/0)", col, col);
        if (s.cond == "moving") return fmt::format("($14 > 0 ? ${} : 1/0)", col);
        return fmt::format("{}", col);
      };
      gp << fmt::format("set output '{}'\nset multiplot layout 1,2\n", (dir / (s.name + ".svg")).string());
      for (int a = 0; a < 2; ++a) {
        const int col = a == 0 ? s.col_p : s.col_y;
        gp << fmt::format("set title '{} residual vs {}'\nset xlabel '{}'\nset ylabel 'arcsec'\n", a == 0 ? "pitch" : "yaw",
                          s.name, s.xlabel);
        gp << fmt::format("plot '{0}' using {1}:{2} with points pt 7 ps 0.3 lc rgb '#c0c0c0' title 'before', "
                          "'{0}' using {1}:{3} with points pt 7 ps 0.3 lc rgb '#1f5fbf' title 'after'\n",
                          (dir / "rows.dat").string(), x(col), a == 0 ? 10 : 11, a == 0 ? 12 : 13);
      }
      gp << "unset multiplot\n";
    }
    // The residual map over the field: one arrow per dwell, scaled by a power of ten so the largest
    // is at most a tenth of the field (the same factor before and after).
    double field = 1, largest = 0;
    for (const auto& s : r.steps) {
      if (s.kind != StepKind::dwell) continue;
      double m[4] = {0, 0, 0, 0};
      for (size_t i = s.begin; i < s.end; ++i) {
        m[0] += r.ref[0][i]; m[1] += r.ref[1][i]; m[2] += r.res[0][i]; m[3] += r.res[1][i];
      }
      const double k = 1.0 / static_cast<double>(s.end - s.begin);
      field = std::max({field, std::abs(m[0] * k), std::abs(m[1] * k)});
      largest = std::max(largest, std::hypot(m[2] * k, m[3] * k));
    }
    const double scale = largest > 0 ? std::pow(10.0, std::floor(std::log10(0.1 * field / largest))) : 1.0;
    gp << fmt::format("set output '{}'\nset size ratio -1\nset multiplot layout 1,2\n", (dir / "field.svg").string());
    for (int k = 0; k < 2; ++k) {
      gp << fmt::format("set title 'dwell residuals over the field, {} (arrows x{:g})'\nset xlabel 'pitch, arcsec'\n"
                        "set ylabel 'yaw, arcsec'\n",
                        k == 0 ? "before" : "after", scale);
      gp << fmt::format("plot '{0}' using 1:2:({4:g}*${1}):({4:g}*${2}) with vectors head size 8,20 lc rgb '{3}' notitle, "
                        "'{0}' using 1:2 with points pt 7 ps 0.3 lc rgb 'black' notitle\n",
                        (dir / "dwells.dat").string(), k == 0 ? 3 : 5, k == 0 ? 4 : 6, k == 0 ? "#c03020" : "#1f5fbf", scale);
    }
    gp << "unset multiplot\n";
    gp.close();
    const std::string cmd = fmt::format("gnuplot '{}' 2>'{}'", (dir / "plots.gp").string(), (dir / "gnuplot.log").string());
    const int rc = std::system(cmd.c_str());
    if (rc == 0) {
      for (const auto& s : specs) figures.push_back({"Residual against " + s.name, slurp(dir / (s.name + ".svg"))});
      figures.push_back({"Residual map over the field (dwell means)", slurp(dir / "field.svg")});
    } else {
      gnuplot_note = "gnuplot failed (" + slurp(dir / "gnuplot.log") + "): figures left out.";
    }
    // FPSS_DIAGNOSIS_KEEP_FIGURES=1 keeps the gnuplot script and data (to redraw them elsewhere).
    if (const char* keep = std::getenv("FPSS_DIAGNOSIS_KEEP_FIGURES"); keep && std::string(keep) == "1") {
      std::fprintf(stderr, "diagnosis report: figures kept in %s\n", dir.c_str());
    } else {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  } else {
    gnuplot_note = "gnuplot is not installed: figures left out (tables below).";
  }

  std::ostringstream h;
  h << "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>Sim-to-real gap: " << esc(d.source)
    << "</title>\n<style>body{font-family:sans-serif;max-width:1000px;margin:1em auto}"
       "table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:2px 6px;text-align:left}"
       "th{background:#eee}.num{text-align:right}</style></head><body>\n";
  h << "<h1>Sim-to-real gap diagnosis</h1>\n<p>Recording: <code>" << esc(d.source) << "</code></p>\n";
  h << "<table><tr><th>cause</th><td>" << esc(d.cause) << "</td></tr>";
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
  h << fmt::format("<tr><th>noise floor</th><td class=num>{:.4f} arcsec</td></tr></table>\n", d.noise_floor_arcsec);
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

  h << "<h2>Candidates (best first)</h2>\n<table><tr><th>effect</th><th>params</th><th>k</th><th>fit RMS</th>"
       "<th>held-out RMS</th><th>score</th></tr>\n";
  for (const auto& e : d.effects) {
    std::string params = e.params.dump();
    if (params.size() > 160) params = params.substr(0, 157) + "...";
    h << fmt::format("<tr><td>{}</td><td><code>{}</code></td><td class=num>{}</td><td class=num>{:.4f}</td>"
                     "<td class=num>{:.4f}</td><td class=num>{:.1f}</td></tr>\n",
                     esc(e.name), esc(params), e.parameters, e.fit_rms_arcsec, e.heldout_rms_arcsec, e.score);
  }
  h << "</table>\n";
  if (!d.not_observable.empty()) {
    h << "<h2>Not observable in this recording</h2>\n<ul>\n";
    for (const auto& n : d.not_observable) h << "<li><b>" << esc(n.name) << "</b>: " << esc(n.reason) << "</li>\n";
    h << "</ul>\n";
  }
  h << "<h2>Split</h2>\n<pre>" << esc(d.split.dump(1)) << "</pre>\n";
  h << "<h2>Figures</h2>\n";
  if (!gnuplot_note.empty()) h << "<p>" << esc(gnuplot_note) << "</p>\n";
  for (const auto& f : figures) {
    std::string svg = f.svg;
    if (const auto p = svg.find("<svg"); p != std::string::npos) svg = svg.substr(p);  // drop the XML prolog
    h << "<h3>" << esc(f.title) << "</h3>\n" << svg << "\n";
  }
  h << "</body></html>\n";

  write_text_atomic(html_path, h.str());
}

}  // namespace fpss
