#include "stand/report/budget_section.h"

#include <fmt/format.h>

namespace fpss {

// calibration.json's GUM budget of each axis (uncertainties.<axis>.budget, at the angle of the
// largest expanded uncertainty), shown as written there.
void budget_section(std::string& h, const ReportInput& in) {
  const auto& extra = in.calibration.extra;
  if (!extra.contains("uncertainties") || !extra["uncertainties"].is_object()) return;
  const auto& un = extra["uncertainties"];
  std::string body;
  for (const char* axis : {"pitch", "yaw"}) {
    if (!un.contains(axis) || !un[axis].is_object()) continue;
    const auto& a = un[axis];
    if (!a.contains("budget") || !a["budget"].is_array() || a["budget"].empty() || !a["coverage_factor"].is_number() ||
        !a["expanded_uncertainty_max_arcsec"].is_number() || !a["budget_angle_arcsec"].is_number()) {
      continue;
    }
    const auto num = [](const nlohmann::json& v, const char* fmt_spec) {
      return v.is_number() ? fmt::format(fmt::runtime(fmt_spec), v.get<double>()) : std::string("&infin;");
    };
    body += fmt::format("<h3>{} at {:.1f} arcsec</h3>\n<table>\n<tr><th class=\"l\">source</th><th>type</th>"
                        "<th>u (arcsec)</th><th>degrees of freedom</th></tr>\n",
                        axis, a["budget_angle_arcsec"].get<double>());
    for (const auto& e : a["budget"]) {
      if (!e.is_object() || !e.contains("source") || !e["source"].is_string() || !e.contains("u_arcsec")) continue;
      body += fmt::format("<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
                          html_escape(e["source"].get<std::string>()),
                          e.contains("type") && e["type"].is_string() ? html_escape(e["type"].get<std::string>()) : "",
                          num(e["u_arcsec"], "{:.4f}"), num(e.value("dof", nlohmann::json()), "{:.0f}"));
    }
    const double k = a["coverage_factor"].get<double>(), big_u = a["expanded_uncertainty_max_arcsec"].get<double>();
    body += fmt::format("<tr><th class=\"l\">combined u</th><td></td><td>{:.4f}</td><td>{}</td></tr>\n"
                        "<tr><th class=\"l\">expanded U (k = {:.3f}, 95 %)</th><td></td><td>{:.4f}</td><td></td></tr>\n"
                        "</table>\n",
                        big_u / k, num(a.value("dof_eff", nlohmann::json()), "{:.0f}"), k, big_u);
  }
  if (body.empty()) return;
  h += "<section id=\"budget\"><h2>Uncertainty budget</h2>\n<p>Of the calibrated angle (fitted minus true), at the "
       "listed angle with the largest expanded uncertainty U = k u; k from the Welch-Satterthwaite degrees of freedom "
       "(GUM; calibration.json <code>uncertainties.&lt;axis&gt;.budget</code>, docs/calibration.md).</p>\n" +
       body + "</section>\n";
}

}  // namespace fpss
