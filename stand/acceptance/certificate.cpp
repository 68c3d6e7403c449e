// The acceptance certificate: acceptance.json's content, its plain-text and HTML forms.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "stand/acceptance/acceptance.h"
#include "stand/report/report.h"

namespace fpss {

namespace {

nlohmann::ordered_json number_or_null(double v) {
  return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr);
}

nlohmann::ordered_json rule_json(const DecisionRule& r) {
  nlohmann::ordered_json j{{"rule", to_string(r.kind)}};
  if (r.kind == DecisionRuleKind::guarded) j["guard_multiple"] = r.guard_multiple;
  if (r.kind == DecisionRuleKind::risk) j["max_false_accept"] = r.max_false_accept;
  j["statement"] = "Decision rule: " + rule_sentence(r) + ".";
  return j;
}

// A guard multiple as the rule's sentence writes it (1.0, 1.5).
std::string multiple_text(double m) { return m == std::floor(m) ? fmt::format("{:.1f}", m) : fmt::format("{}", m); }

// Why the rule decided otherwise than simple acceptance would ("" when it did not): only a
// value within its limit can differ, passing under simple and conditional under the others.
std::string outcome_reason(const Criterion& k, const DecisionRule& r) {
  if (!k.measured || k.decision.outcome == k.simple_outcome) return "";
  const double v = *k.measured, a = k.decision.acceptance_limit;
  if (r.kind == DecisionRuleKind::guarded) {
    return fmt::format("the value {:.4g} ({}) is within the limit {} {:.4g} but beyond the acceptance limit {:.4g}: the limit less "
                       "the guard band w = {} x U = {:.4g}; the true value may lie beyond the limit (U = {:.4g}, "
                       "95 %), so the outcome is {} where simple acceptance would pass it",
                       v, k.unit, k.relation, k.limit, a, multiple_text(r.guard_multiple), std::fabs(k.limit - a), k.combined.U,
                       to_string(k.decision.outcome));
  }
  return fmt::format("the value {:.4g} ({}) is within the limit {} {:.4g} but beyond the acceptance limit {:.4g}: the probability "
                     "that the true value lies beyond the limit is {:.3f}, more than the {} allowed, so the outcome is "
                     "{} where simple acceptance would pass it",
                     v, k.unit, k.relation, k.limit, a, k.decision.false_accept, r.max_false_accept,
                     to_string(k.decision.outcome));
}

// The calibrated angle's expanded uncertainty per axis, then its budget in one line.
std::string calibration_uncertainty_text(const nlohmann::ordered_json& cu) {
  std::string s = "\nCalibrated angle (calibration.json; fitted minus true, the worst listed angle):\n";
  for (const auto& [axis, a] : cu.items()) {
    const auto num = [](const nlohmann::ordered_json& v) { return v.is_number() ? fmt::format("{:.0f}", v.get<double>()) : "inf"; };
    std::string parts;
    for (const auto& e : a["budget"]) {
      if (!e.is_object() || !e.contains("u_arcsec") || !e["u_arcsec"].is_number()) continue;
      parts += fmt::format("{}{} ({}) {:.4f}", parts.empty() ? "" : ", ", e.value("source", std::string()),
                           e.value("type", std::string()), e["u_arcsec"].get<double>());
    }
    s += fmt::format("  {:<5} U = {:.4f} arcsec (k = {:.3f}, 95 %, nu_eff {}) at {:.1f} arcsec; budget: {}\n", axis,
                     a["expanded_uncertainty_max_arcsec"].get<double>(),
                     a["coverage_factor"].is_number() ? a["coverage_factor"].get<double>() : 0.0, num(a["dof_eff"]),
                     a["budget_angle_arcsec"].is_number() ? a["budget_angle_arcsec"].get<double>() : 0.0, parts);
  }
  return s;
}

}  // namespace

nlohmann::json calibration_uncertainty(const nlohmann::json& uncertainties) {
  nlohmann::json out = nlohmann::json::object();
  for (const char* axis : {"pitch", "yaw"}) {
    if (!uncertainties.is_object() || !uncertainties.contains(axis) || !uncertainties[axis].is_object()) continue;
    const nlohmann::json& a = uncertainties[axis];
    if (!a.contains("expanded_uncertainty_max_arcsec") || !a["expanded_uncertainty_max_arcsec"].is_number()) continue;
    nlohmann::json one = nlohmann::json::object();
    for (const char* k : {"expanded_uncertainty_max_arcsec", "coverage_factor", "dof_eff", "budget_angle_arcsec", "budget"}) {
      one[k] = a.value(k, nlohmann::json());
    }
    out[axis] = std::move(one);
  }
  return out.empty() ? nlohmann::json() : out;
}

nlohmann::ordered_json certificate_json(const Judgement& j, const AcceptanceLimits& limits, const CertificateInfo& info) {
  nlohmann::ordered_json c;
  c["format"] = "fpss-stand acceptance/1";
  c["verdict"] = to_string(j.outcome);
  c["passed"] = j.passed;
  c["unit"] = info.unit;
  c["stand"] = {{"identity", info.stand}, {"detail", info.stand_detail}};
  c["software"] = {{"name", "fpss-stand"}, {"version", info.software_version}};
  c["procedure"] = {{"name", info.procedure_name}, {"file", info.procedure_file}, {"sha256", info.procedure_sha256}};
  c["limits"] = {{"name", limits.name}, {"file", limits.origin}, {"sha256", limits.sha256}};
  if (!info.reference.is_null()) c["reference"] = info.reference;  // the gimbal's calibration applied
  c["decision_rule"] = rule_json(j.rule);
  c["run"] = {{"id", info.run_id},
              {"dir", info.run_dir},
              {"outcome", info.run_outcome},
              {"reason", info.run_reason},
              {"points_planned", info.points_planned},
              {"points_completed", info.points_completed}};
  c["date_utc"] = info.date_utc;
  c["calibration"] = info.calibration_file.empty() ? nlohmann::ordered_json(nullptr)
                                                   : nlohmann::ordered_json(info.calibration_file);
  if (!info.calibration_uncertainty.is_null()) c["calibration_uncertainty"] = info.calibration_uncertainty;
  nlohmann::ordered_json crit = nlohmann::ordered_json::array();
  for (const auto& k : j.criteria) {
    const nlohmann::ordered_json measured = k.measured ? nlohmann::ordered_json(*k.measured) : nlohmann::ordered_json();
    crit.push_back(nlohmann::ordered_json{
        {"id", k.id}, {"title", k.title}, {"axis", k.axis},
        {"measured", measured}, {"uncertainty", k.uncertainty},
        {"expanded_uncertainty", k.combined.U}, {"coverage_factor", k.combined.k},
        {"dof_eff", number_or_null(k.combined.dof_eff)}, {"budget", budget_json(k.budget, "u")},
        {"limit", k.limit}, {"acceptance_limit", k.decision.acceptance_limit}, {"relation", k.relation},
        {"unit", k.unit}, {"outcome", to_string(k.decision.outcome)}, {"outcome_reason", outcome_reason(k, j.rule)},
        {"passed", k.passed}, {"limit_key", k.limit_key}, {"source", k.source}, {"detail", k.detail}});
  }
  c["criteria"] = crit;
  c["failed"] = j.failed();
  c["conditional"] = j.conditional();
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

int value_decimals(const nlohmann::ordered_json& k) {
  const std::string unit = k["unit"].get<std::string>();
  return unit == "points" ? 0 : unit == "deg" || unit == "fraction" ? 4 : 3;
}

// The expanded uncertainty U (95 %), "-" when the value is exact or absent.
std::string expanded_text(const nlohmann::ordered_json& k) {
  const double U = k["expanded_uncertainty"].get<double>();
  if (k["measured"].is_null() || !(U > 0)) return "-";
  return fmt::format("{:.{}f}", U, value_decimals(k));
}

std::string acceptance_limit_text(const nlohmann::ordered_json& k) {
  return fmt::format("{:.{}f}", k["acceptance_limit"].get<double>(), std::max(value_decimals(k), 1));
}

std::string outcome_word(const std::string& o) { return o == "pass" ? "pass" : o == "fail" ? "FAIL" : "CONDITIONAL"; }

std::string upper_word(const std::string& o) { return o == "pass" ? "PASS" : o == "fail" ? "FAIL" : "CONDITIONAL"; }

// A budget in one line: each contribution, then u, nu_eff, k and U.
std::string budget_text(const nlohmann::ordered_json& k) {
  if (k["budget"].empty()) return "";
  std::string s;
  for (const auto& e : k["budget"]) {
    s += fmt::format("{} (type {}, c = {:.4g}, u = {:.3g}, nu = {}); ", e["source"].get<std::string>(),
                     e["type"].get<std::string>(), e["sensitivity"].get<double>(), e["u"].get<double>(),
                     e["dof"].is_null() ? std::string("inf") : fmt::format("{:.0f}", e["dof"].get<double>()));
  }
  return s + fmt::format("combined u = {:.3g}, nu_eff = {}, k = {:.3f}, U = {:.3g}", k["uncertainty"].get<double>(),
                         k["dof_eff"].is_null() ? std::string("inf") : fmt::format("{:.1f}", k["dof_eff"].get<double>()),
                         k["coverage_factor"].get<double>(), k["expanded_uncertainty"].get<double>());
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
  s += fmt::format("Verdict:    {}\n", upper_word(c["verdict"].get<std::string>()));
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
  s += fmt::format("{:<28} {:>22} {:>9} {:>10} {:>10} {:<8} {}\n", "criterion", "measured (+- 1 sigma)", "U (95 %)",
                   "limit", "accept at", "unit", "result");
  for (const auto& k : c["criteria"]) {
    s += fmt::format("{:<28} {:>22} {:>9} {:>10} {:>10} {:<8} {}\n", k["id"].get<std::string>(), value_text(k),
                     expanded_text(k), limit_text(k), acceptance_limit_text(k), k["unit"].get<std::string>(),
                     outcome_word(k["outcome"].get<std::string>()));
  }
  if (c.contains("calibration_uncertainty")) s += calibration_uncertainty_text(c["calibration_uncertainty"]);
  s += fmt::format("\n{}\n", c["decision_rule"]["statement"].get<std::string>());
  std::string why;
  for (const auto& k : c["criteria"]) {
    if (!k["outcome_reason"].get<std::string>().empty()) {
      why += fmt::format("- {}: {}\n", k["id"].get<std::string>(), k["outcome_reason"].get<std::string>());
    }
  }
  if (!why.empty()) s += fmt::format("Where this rule decides otherwise than simple acceptance:\n{}", why);
  s += "\nHow each was measured and where its limit comes from:\n";
  for (const auto& k : c["criteria"]) {
    s += fmt::format("- {}: {}\n", k["id"].get<std::string>(), k["detail"].get<std::string>());
    if (const std::string b = budget_text(k); !b.empty()) s += fmt::format("    uncertainty: {}\n", b);
    s += fmt::format("    limit: {}\n", k["source"].get<std::string>());
  }
  return s;
}

std::string certificate_html(const nlohmann::ordered_json& c) {
  const std::string verdict = c["verdict"].get<std::string>();
  const auto colour = [](const std::string& o) { return o == "pass" ? "#1a7f37" : o == "fail" ? "#b42318" : "#8a6d00"; };
  std::string h;
  h += fmt::format("<p class=\"verdict\" style=\"font-size:1.3em;font-weight:bold;color:{}\">Acceptance: {}</p>\n",
                   colour(verdict), upper_word(verdict));
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
  h += "<tr><th>criterion</th><th>measured (&plusmn; 1&sigma;)</th><th>U (95 %)</th><th>limit</th><th>acceptance limit</th>"
       "<th>unit</th><th>result</th><th>how measured</th><th>uncertainty budget</th><th>source of the limit</th></tr>\n";
  for (const auto& k : c["criteria"]) {
    const std::string o = k["outcome"].get<std::string>();
    std::string how = k["detail"].get<std::string>();
    if (!k["outcome_reason"].get<std::string>().empty()) how += "; " + k["outcome_reason"].get<std::string>();
    h += fmt::format(
        "<tr><td title=\"{}\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>"
        "<td style=\"font-weight:bold;color:{}\">{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
        html_escape(k["title"].get<std::string>()), html_escape(k["id"].get<std::string>()), html_escape(value_text(k)),
        html_escape(expanded_text(k)), html_escape(limit_text(k)), html_escape(acceptance_limit_text(k)),
        html_escape(k["unit"].get<std::string>()), colour(o), outcome_word(o), html_escape(how),
        html_escape(budget_text(k)), html_escape(k["source"].get<std::string>()));
  }
  h += "</table>\n<p class=\"decision-rule\">" + html_escape(c["decision_rule"]["statement"].get<std::string>()) + "</p>\n";
  h += "<h3>Verification and rest points</h3>\n<table class=\"points\">\n";
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
