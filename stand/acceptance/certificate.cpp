// The acceptance certificate: acceptance.json's content, its plain-text and HTML forms.
#include <fmt/format.h>

#include <cmath>

#include "stand/acceptance/acceptance.h"
#include "stand/report/report.h"

namespace fpss {

nlohmann::ordered_json certificate_json(const Judgement& j, const AcceptanceLimits& limits, const CertificateInfo& info) {
  nlohmann::ordered_json c;
  c["format"] = "fpss-stand acceptance/1";
  c["verdict"] = j.passed ? "pass" : "fail";
  c["passed"] = j.passed;
  c["unit"] = info.unit;
  c["stand"] = {{"identity", info.stand}, {"detail", info.stand_detail}};
  c["software"] = {{"name", "fpss-stand"}, {"version", info.software_version}};
  c["procedure"] = {{"name", info.procedure_name}, {"file", info.procedure_file}, {"sha256", info.procedure_sha256}};
  c["limits"] = {{"name", limits.name}, {"file", limits.origin}, {"sha256", limits.sha256}};
  if (!info.reference.is_null()) c["reference"] = info.reference;  // the gimbal's calibration applied
  c["run"] = {{"id", info.run_id},
              {"dir", info.run_dir},
              {"outcome", info.run_outcome},
              {"reason", info.run_reason},
              {"points_planned", info.points_planned},
              {"points_completed", info.points_completed}};
  c["date_utc"] = info.date_utc;
  c["calibration"] = info.calibration_file.empty() ? nlohmann::ordered_json(nullptr)
                                                   : nlohmann::ordered_json(info.calibration_file);
  nlohmann::ordered_json crit = nlohmann::ordered_json::array();
  for (const auto& k : j.criteria) {
    const nlohmann::ordered_json measured = k.measured ? nlohmann::ordered_json(*k.measured) : nlohmann::ordered_json();
    crit.push_back(nlohmann::ordered_json{
        {"id", k.id}, {"title", k.title}, {"axis", k.axis},
        {"measured", measured}, {"uncertainty", k.uncertainty},
        {"limit", k.limit}, {"relation", k.relation}, {"unit", k.unit}, {"passed", k.passed},
        {"limit_key", k.limit_key}, {"source", k.source}, {"detail", k.detail}});
  }
  c["criteria"] = crit;
  c["failed"] = j.failed();
  c["outliers"] = j.outliers.to_json();
  nlohmann::ordered_json pts = nlohmann::ordered_json::array();
  for (const auto& p : j.points) {
    nlohmann::ordered_json e{{"step", p.step}, {"role", p.role}, {"phase", std::string(to_string(p.phase))},
                             {"ref_pitch_arcsec", p.ref_pitch_arcsec}, {"ref_yaw_arcsec", p.ref_yaw_arcsec},
                             {"frames", p.frames},
                             {"outlier_frames_pitch", p.outliers_pitch}, {"outlier_frames_yaw", p.outliers_yaw},
                             {"error_pitch_arcsec", p.error_pitch_arcsec}, {"error_yaw_arcsec", p.error_yaw_arcsec},
                             {"se_pitch_arcsec", p.se_pitch_arcsec}, {"se_yaw_arcsec", p.se_yaw_arcsec}};
    if (p.role == PointRole::rest) {
      e["jitter_3sigma_pitch_arcsec"] = p.jitter3_pitch_arcsec;
      e["jitter_3sigma_yaw_arcsec"] = p.jitter3_yaw_arcsec;
    }
    pts.push_back(std::move(e));
  }
  c["points"] = pts;
  return c;
}

namespace {

std::string value_text(const nlohmann::ordered_json& k) {
  if (k["measured"].is_null()) return "not measured";
  const std::string unit = k["unit"].get<std::string>();
  const double v = k["measured"].get<double>(), u = k["uncertainty"].get<double>();
  const int dec = unit == "points" ? 0 : unit == "deg" || unit == "fraction" ? 4 : 3;
  if (u > 0) return fmt::format("{:.{}f} +- {:.{}f}", v, dec, u, dec);
  return fmt::format("{:.{}f}", v, dec);
}

std::string limit_text(const nlohmann::ordered_json& k) {
  const std::string unit = k["unit"].get<std::string>();
  const int dec = unit == "points" ? 0 : unit == "deg" ? 2 : unit == "fraction" ? 4 : 1;
  return fmt::format("{} {:.{}f}", k["relation"].get<std::string>(), k["limit"].get<double>(), dec);
}

}  // namespace

std::string certificate_text(const nlohmann::ordered_json& c) {
  std::string s;
  s += "FPSS UNIT ACCEPTANCE CERTIFICATE\n\n";
  s += fmt::format("Verdict:    {}\n", c["passed"].get<bool>() ? "PASS" : "FAIL");
  s += fmt::format("Unit:       {}\n", c["unit"].get<std::string>());
  s += fmt::format("Stand:      {}\n", c["stand"]["identity"].get<std::string>());
  s += fmt::format("Software:   fpss-stand {}\n", c["software"]["version"].get<std::string>());
  s += fmt::format("Procedure:  {} ({}), sha256 {}\n", c["procedure"]["name"].get<std::string>(),
                   c["procedure"]["file"].get<std::string>(), c["procedure"]["sha256"].get<std::string>());
  s += fmt::format("Limits:     {} ({}), sha256 {}\n", c["limits"]["name"].get<std::string>(),
                   c["limits"]["file"].get<std::string>(), c["limits"]["sha256"].get<std::string>());
  if (c.contains("reference")) {
    s += fmt::format("Reference:  certificate {} of {}, {} ({}), sha256 {}\n", c["reference"]["certificate"].get<std::string>(),
                     c["reference"]["date"].get<std::string>(), c["reference"]["lab"].get<std::string>(),
                     c["reference"]["file"].get<std::string>(), c["reference"]["sha256"].get<std::string>());
  }
  s += fmt::format("Run:        {} ({}, {}/{} points)\n", c["run"]["id"].get<std::string>(),
                   c["run"]["outcome"].get<std::string>(), c["run"]["points_completed"].get<int64_t>(),
                   c["run"]["points_planned"].get<int64_t>());
  if (!c["run"]["reason"].get<std::string>().empty()) {
    s += fmt::format("            stopped: {}\n", c["run"]["reason"].get<std::string>());
  }
  if (c.contains("operator")) {
    s += fmt::format("Operator:   {} (signed off {})\n", c["operator"].get<std::string>(),
                     c.value("signed_off_utc", std::string()));
  }
  s += fmt::format("Date (UTC): {}\n\n", c["date_utc"].get<std::string>());
  s += fmt::format("{:<28} {:>22} {:>10} {:<8} {}\n", "criterion", "measured (+- 1 sigma)", "limit", "unit", "result");
  for (const auto& k : c["criteria"]) {
    s += fmt::format("{:<28} {:>22} {:>10} {:<8} {}\n", k["id"].get<std::string>(), value_text(k), limit_text(k),
                     k["unit"].get<std::string>(), k["passed"].get<bool>() ? "pass" : "FAIL");
  }
  s += "\nHow each was measured and where its limit comes from:\n";
  for (const auto& k : c["criteria"]) {
    s += fmt::format("- {}: {}\n    limit: {}\n", k["id"].get<std::string>(), k["detail"].get<std::string>(),
                     k["source"].get<std::string>());
  }
  return s;
}

std::string certificate_html(const nlohmann::ordered_json& c) {
  const bool pass = c["passed"].get<bool>();
  std::string h;
  h += fmt::format("<p class=\"verdict\" style=\"font-size:1.3em;font-weight:bold;color:{}\">Acceptance: {}</p>\n",
                   pass ? "#1a7f37" : "#b42318", pass ? "PASS" : "FAIL");
  h += "<table>\n";
  auto row = [&](const char* k, const std::string& v) {
    h += fmt::format("<tr><th style=\"text-align:left\">{}</th><td>{}</td></tr>\n", k, html_escape(v));
  };
  row("Unit", c["unit"].get<std::string>());
  if (c.contains("operator")) {
    row("Operator", fmt::format("{} (signed off {})", c["operator"].get<std::string>(),
                                c.value("signed_off_utc", std::string())));
  }
  row("Stand", c["stand"]["identity"].get<std::string>());
  row("Software", "fpss-stand " + c["software"]["version"].get<std::string>());
  row("Procedure", fmt::format("{} ({}), sha256 {}", c["procedure"]["name"].get<std::string>(),
                               c["procedure"]["file"].get<std::string>(), c["procedure"]["sha256"].get<std::string>()));
  row("Limits", fmt::format("{} ({}), sha256 {}", c["limits"]["name"].get<std::string>(),
                            c["limits"]["file"].get<std::string>(), c["limits"]["sha256"].get<std::string>()));
  row("Run", fmt::format("{} ({}, {}/{} points){}", c["run"]["id"].get<std::string>(),
                         c["run"]["outcome"].get<std::string>(), c["run"]["points_completed"].get<int64_t>(),
                         c["run"]["points_planned"].get<int64_t>(),
                         c["run"]["reason"].get<std::string>().empty() ? "" : ": " + c["run"]["reason"].get<std::string>()));
  row("Date (UTC)", c["date_utc"].get<std::string>());
  h += "</table>\n<h3>Criteria</h3>\n<table class=\"criteria\">\n";
  h += "<tr><th>criterion</th><th>measured (&plusmn; 1&sigma;)</th><th>limit</th><th>unit</th><th>result</th>"
       "<th>how measured</th><th>source of the limit</th></tr>\n";
  for (const auto& k : c["criteria"]) {
    const bool ok = k["passed"].get<bool>();
    h += fmt::format(
        "<tr><td title=\"{}\">{}</td><td>{}</td><td>{}</td><td>{}</td><td style=\"font-weight:bold;color:{}\">{}</td>"
        "<td>{}</td><td>{}</td></tr>\n",
        html_escape(k["title"].get<std::string>()), html_escape(k["id"].get<std::string>()), html_escape(value_text(k)),
        html_escape(limit_text(k)), html_escape(k["unit"].get<std::string>()), ok ? "#1a7f37" : "#b42318",
        ok ? "pass" : "FAIL", html_escape(k["detail"].get<std::string>()), html_escape(k["source"].get<std::string>()));
  }
  h += "</table>\n<h3>Verification and rest points</h3>\n<table class=\"points\">\n";
  h += "<tr><th>step</th><th>role</th><th>pitch (deg)</th><th>yaw (deg)</th><th>frames</th>"
       "<th>error pitch (arcsec)</th><th>error yaw (arcsec)</th><th>jitter 3&sigma; pitch</th><th>jitter 3&sigma; yaw</th></tr>\n";
  for (const auto& p : c["points"]) {
    const bool rest = p["role"] == "rest";
    h += fmt::format("<tr><td>{}</td><td>{}{}</td><td>{:+.4f}</td><td>{:+.4f}</td><td>{}</td><td>{:+.3f}</td><td>{:+.3f}</td>"
                     "<td>{}</td><td>{}</td></tr>\n",
                     p["step"].get<int64_t>(), p["role"].get<std::string>(),
                     p["phase"] == "null" && !rest ? " (null)" : "", p["ref_pitch_arcsec"].get<double>() / 3600.0,
                     p["ref_yaw_arcsec"].get<double>() / 3600.0, p["frames"].get<int64_t>(),
                     p["error_pitch_arcsec"].get<double>(), p["error_yaw_arcsec"].get<double>(),
                     rest ? fmt::format("{:.3f}", p["jitter_3sigma_pitch_arcsec"].get<double>()) : "",
                     rest ? fmt::format("{:.3f}", p["jitter_3sigma_yaw_arcsec"].get<double>()) : "");
  }
  h += "</table>\n";
  return h;
}

}  // namespace fpss
