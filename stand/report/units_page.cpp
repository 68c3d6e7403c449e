#include "stand/report/units_page.h"

#include <fmt/format.h>

#include "base/text_file.h"
#include "calib/coefficients.h"
#include "stand/catalogue/catalogue.h"
#include "stand/report/report.h"

namespace fpss {

namespace fs = std::filesystem;

namespace {

// The unit's Table 1 (calibration.json's residuals block): its numbers, never a second computation.
std::string table1_html(const fs::path& calibration) {
  const CoefficientSet c = load_coefficients(calibration);
  if (!c.extra.contains("residuals")) return "<p class=\"note\">No residuals block in its calibration.json.</p>\n";
  std::string h = "<table class=\"table1\"><tr><th class=\"l\">axis</th><th>mean |r| (arcsec)</th><th>sd (arcsec)</th>"
                  "<th>rms (arcsec)</th><th>max |r| (arcsec)</th><th>points</th></tr>\n";
  for (const char* axis : {"pitch", "yaw"}) {
    const auto& r = c.extra["residuals"];
    if (!r.contains(axis)) continue;
    const auto& a = r[axis];
    const auto stats = AxisResidualStats::from_json(a, calibration.string());
    auto num = [](const std::optional<double>& v) { return v ? fmt::format("{:.4f}", *v) : std::string("&ndash;"); };
    h += fmt::format("<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n", axis,
                     num(stats.mean_abs_arcsec), num(stats.sd_arcsec), num(stats.rms_arcsec), num(stats.max_abs_arcsec),
                     stats.points ? std::to_string(*stats.points) : "&ndash;");
  }
  return h + "</table>\n";
}

}  // namespace

fs::path write_units_report(const fs::path& run_dir, const RunFile& run, const std::vector<UnitReport>& units) {
  std::string h = "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
  h += fmt::format("<title>Run {} ({} units)</title>\n", html_escape(run.id_or(run_dir)), units.size());
  h += "<style>body{font-family:sans-serif;margin:1.5em auto;max-width:1100px;color:#222}"
       "table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:right}"
       "th.l,td.l{text-align:left}h2{border-bottom:1px solid #ccc}</style>\n</head>\n<body>\n";
  h += fmt::format("<h1>Run {}: {} units on one gimbal</h1>\n<p>Procedure {}, started {}, outcome {}.</p>\n",
                   html_escape(run.id_or(run_dir)), units.size(), html_escape(run.procedure.name),
                   html_escape(run.started_utc), html_escape(run.outcome));
  h += verdict_banner_html(run_verdict(run));
  h += "<h2>How the units sit relative to the first</h2>\n<table id=\"relative\"><tr><th class=\"l\">unit</th>"
       "<th>boresight pitch (arcsec)</th><th>1 sigma</th><th>boresight yaw (arcsec)</th><th>1 sigma</th>"
       "<th>roll (arcsec)</th><th>1 sigma</th></tr>\n";
  for (const auto& u : units) {
    if (!u.unit.relative) continue;
    const RunFileRelative& r = *u.unit.relative;
    h += fmt::format("<tr><td class=\"l\">{} to {}</td><td>{:+.3f}</td><td>{:.3f}</td><td>{:+.3f}</td><td>{:.3f}</td>"
                     "<td>{:+.2f}</td><td>{:.2f}</td></tr>\n",
                     html_escape(u.unit.serial), html_escape(r.to), r.boresight_pitch_arcsec,
                     r.boresight_pitch_sigma_arcsec, r.boresight_yaw_arcsec, r.boresight_yaw_sigma_arcsec, r.roll_arcsec,
                     r.roll_sigma_arcsec);
  }
  h += "</table>\n<p>The boresight is where a unit's electrical null (zero counts) lies by its calibration; the roll is "
       "about the boresight, from the cross-talk between its axes. The same numbers as run.json's units[].relative.</p>\n";
  for (const auto& u : units) {
    const std::string id = "unit-" + unit_folder_name(u.unit.serial);
    h += fmt::format("<section id=\"{}\">\n<h2>Unit {}</h2>\n", html_escape(id), html_escape(u.unit.serial));
    h += verdict_banner_html(u.verdict, "verdict-" + unit_folder_name(u.unit.serial));
    h += fmt::format("<p>Outcome {}{}; sensor {} at {}.</p>\n", html_escape(u.unit.outcome),
                     u.unit.loss_cause ? " (" + html_escape(*u.unit.loss_cause) + ")" : "",
                     html_escape(u.unit.sensor_id.value_or("?")), html_escape(u.unit.endpoint.value_or("?")));
    if (u.unit.calibration && fs::exists(run_dir / *u.unit.calibration)) h += table1_html(run_dir / *u.unit.calibration);
    h += "<ul>\n";
    for (const auto& f : {u.unit.samples, u.unit.calibration, u.unit.acceptance, u.unit.certificate}) {
      if (f) h += fmt::format("<li><a href=\"{0}\">{0}</a></li>\n", html_escape(*f));
    }
    if (u.report) {
      const std::string rel = fs::relative(*u.report, run_dir).string();
      h += fmt::format("<li><a href=\"{0}\">{0}</a> (its full report)</li>\n", html_escape(rel));
    }
    h += "</ul>\n</section>\n";
  }
  h += "</body>\n</html>\n";
  const fs::path out = run_dir / "report.html";
  write_text_atomic(out, h);
  return out;
}

fs::path write_unit_reports(const fs::path& run_dir, const RunFile& run, const std::vector<UnitFolder>& units) {
  std::vector<UnitReport> pages;
  for (size_t i = 0; i < units.size(); ++i) {
    UnitReport page{run.units->at(i), unit_verdict(run, run.units->at(i)), std::nullopt};
    if (fs::exists(units[i].dir / "calibration.json")) {
      ReportOptions ro;
      ro.recording = units[i].recording;
      ro.verdict = page.verdict;
      page.report = write_report(units[i].dir, ro);
    }
    pages.push_back(std::move(page));
  }
  return write_units_report(run_dir, run, pages);
}

}  // namespace fpss
