// The acceptance limits file: every limit with its source, read with file:line:column errors.
#include <fmt/format.h>

#include "base/errors.h"
#include "base/text_file.h"
#include "procedures/yaml_diag.h"
#include "stand/acceptance/acceptance.h"

namespace fpss {
namespace fs = std::filesystem;

// Limits

namespace {

struct LimitField {
  const char* key;
  Limit AcceptanceLimits::*member;
};

// Bounds on an error or on a region's size: 0 would pass nothing, so each must be > 0.
constexpr LimitField kPositiveLimits[] = {
    {"residual_mean_abs_arcsec", &AcceptanceLimits::residual_mean_abs_arcsec},
    {"residual_max_abs_arcsec", &AcceptanceLimits::residual_max_abs_arcsec},
    {"accuracy_3sigma_arcsec", &AcceptanceLimits::accuracy_3sigma_arcsec},
    {"accuracy_worst_point_arcsec", &AcceptanceLimits::accuracy_worst_point_arcsec},
    {"accuracy_centre_arcsec", &AcceptanceLimits::accuracy_centre_arcsec},
    {"accuracy_radius_arcmin", &AcceptanceLimits::accuracy_radius_arcmin},
    {"jitter_3sigma_arcsec", &AcceptanceLimits::jitter_3sigma_arcsec},
    {"consistency_arcsec", &AcceptanceLimits::consistency_arcsec},
};

// The least a run must reach: 0 asks for nothing, so each may be >= 0.
constexpr LimitField kFloorLimits[] = {
    {"calibrated_range_deg", &AcceptanceLimits::calibrated_range_deg},
    {"verified_extent_deg", &AcceptanceLimits::verified_extent_deg},
    {"verification_points_min", &AcceptanceLimits::verification_points_min},
    {"sun_present_fraction", &AcceptanceLimits::sun_present_fraction},
};

// A share of the frames that may be bad: 0 allows none, so each may be >= 0.
constexpr LimitField kShareLimits[] = {
    {"outlier_frames_fraction", &AcceptanceLimits::outlier_frames_fraction},
};

// One limit's {value, source}: every limit must be given, and its source must say something.
void read_limit(MapReader& limits, const LimitField& f, bool positive, AcceptanceLimits& out, Diagnostics& d) {
  const YAML::Node n = limits.node(f.key);
  if (!n.IsDefined() || n.IsNull()) {
    d.error(limits.mark(), fmt::format("limits: missing \"{}\" (every limit must be given, with its source)", f.key));
    return;
  }
  MapReader one(n, fmt::format("limits.{}", f.key), d);
  if (!one.ok()) return;
  const auto v = positive ? one.positive("value", true) : one.non_negative("value", true);
  const auto src = one.string("source", true);
  if (src && src->find_first_not_of(" \t\r\n") == std::string::npos) {
    d.error(n, fmt::format("limits.{}: source must say where the number comes from", f.key));
  }
  one.finish();
  if (v) (out.*f.member).value = *v;
  if (src) (out.*f.member).source = *src;
}

// decision_rule: {rule: simple} | {rule: guarded[, guard_multiple: m]} | {rule: risk, max_false_accept: p}.
// A field that belongs to another rule is an error, so a file says one thing.
DecisionRule read_decision_rule(const YAML::Node& n, Diagnostics& d) {
  DecisionRule r;
  MapReader m(n, "decision_rule", d);
  if (!m.ok()) return r;
  const auto rule = m.choice("rule", {"simple", "guarded", "risk"}, true);
  if (rule == "guarded") r.kind = DecisionRuleKind::guarded;
  if (rule == "risk") r.kind = DecisionRuleKind::risk;
  const YAML::Node gm = n["guard_multiple"], fa = n["max_false_accept"];
  if (const auto g = m.positive("guard_multiple")) {
    if (*g > 10) d.error(gm, "decision_rule: field guard_multiple: at most 10 (a guard band of 10 U accepts nothing)");
    r.guard_multiple = *g;
  }
  const auto p = m.positive("max_false_accept", r.kind == DecisionRuleKind::risk);
  if (p) {
    if (*p >= 0.5) d.error(fa, "decision_rule: field max_false_accept: a probability below 0.5 (0.5 is the simple rule)");
    r.max_false_accept = *p;
  }
  if (rule && r.kind != DecisionRuleKind::guarded && gm.IsDefined()) {
    d.error(gm, fmt::format("decision_rule: field guard_multiple belongs to rule guarded, not {}", *rule));
  }
  if (rule && r.kind != DecisionRuleKind::risk && fa.IsDefined()) {
    d.error(fa, fmt::format("decision_rule: field max_false_accept belongs to rule risk, not {}", *rule));
  }
  m.finish();
  return r;
}

}  // namespace

fs::path default_limits_path() { return shipped_procedures_dir() / "acceptance_limits.yaml"; }
fs::path default_acceptance_procedure_path() { return shipped_procedures_dir() / "acceptance.yaml"; }

AcceptanceLimits parse_acceptance_limits(const std::string& text, const std::string& origin) {
  Diagnostics d(origin);
  AcceptanceLimits out;
  out.origin = origin;
  out.sha256 = sha256_hex(text);
  const YAML::Node root = parse_yaml(text, d);
  if (!d.empty()) d.throw_if_any();
  MapReader top(root, "limits file", d);
  if (!top.ok()) d.throw_if_any();
  out.name = top.string("name").value_or("");
  out.description = top.string("description").value_or("");
  if (const YAML::Node rule = top.node("decision_rule"); rule.IsDefined()) out.decision_rule = read_decision_rule(rule, d);
  const YAML::Node limits = top.node("limits");
  if (!limits.IsDefined() || limits.IsNull()) {
    d.error(root, "limits file: missing field \"limits\" (a map of limit name -> {value, source})");
  } else {
    MapReader lr(limits, "limits", d);
    for (const auto& f : kPositiveLimits) read_limit(lr, f, true, out, d);
    for (const auto& f : kFloorLimits) read_limit(lr, f, false, out, d);
    for (const auto& f : kShareLimits) read_limit(lr, f, false, out, d);
    lr.finish();
    for (const auto& f : kShareLimits) {
      if ((out.*f.member).value > 1.0) d.error(limits[f.key], fmt::format("limits.{}: value is a fraction, at most 1", f.key));
    }
    if (out.sun_present_fraction.value > 1.0) {
      d.error(limits["sun_present_fraction"], "limits.sun_present_fraction: value is a fraction, at most 1");
    }
  }
  top.finish();
  d.throw_if_any();
  return out;
}

AcceptanceLimits load_acceptance_limits(const fs::path& path) {
  return parse_acceptance_limits(read_text_file(path, "the acceptance limits file"), path.string());
}

}  // namespace fpss
