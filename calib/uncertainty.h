// Uncertainty budgets (GUM): entries, their combination, Welch-Satterthwaite, Student's t, decision rules (ILAC-G8).
#pragma once
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace fpss {

// One contribution to a measured value's uncertainty, already in the value's unit: u = |sensitivity| x
// the input's standard uncertainty. dof is infinite for a type B estimate (and for an A one whose
// sample is taken as large); the source is a free name ("sensor noise", a reference term, ...).
struct BudgetEntry {
  std::string source;
  char type = 'A';           // 'A' (statistics of this recording) or 'B' (other knowledge)
  double sensitivity = 1.0;  // d(value)/d(input)
  double u = 0;              // standard uncertainty contributed to the value
  double dof = std::numeric_limits<double>::infinity();
};

// The combined standard uncertainty, effective degrees of freedom, coverage factor and expanded
// uncertainty of a budget.
struct Combined {
  double u = 0;
  double dof_eff = std::numeric_limits<double>::infinity();
  double k = 0;  // Student's t 97.5 % quantile at floor(dof_eff): 95 % two-sided coverage
  double U = 0;  // k x u
};

// A budget as JSON: [{source, type ("A"|"B"), sensitivity, <u_key>, dof (null: infinite)}], u_key
// "u" in acceptance.json, "u_arcsec" in calibration.json.
nlohmann::ordered_json budget_json(const std::vector<BudgetEntry>& budget, const char* u_key);

// The combined standard uncertainty alone: the root sum of squares of the entries' u.
double root_sum_square(const std::vector<BudgetEntry>& budget);

// Root sum of squares of the entries' u; Welch-Satterthwaite for dof_eff (GUM G.4.1:
// u^4 / sum(u_i^4 / nu_i), infinite entries dropping out, infinite when all are); k at the
// integer below dof_eff (GUM G.4.1 note), at least 1.
Combined combine(const std::vector<BudgetEntry>& budget);

// The regularized incomplete beta function I_x(a, b), a, b > 0, 0 <= x <= 1.
double incomplete_beta(double a, double b, double x);
// Student's t distribution with nu > 0 degrees of freedom (nu infinite: the normal).
double student_t_cdf(double t, double nu);
// Its quantile: the t with student_t_cdf(t, nu) = p, 0 < p < 1.
double student_t_quantile(double p, double nu);

// ---- decision rules (ILAC-G8:09/2019) ----

enum class DecisionRuleKind { simple, guarded, risk };
struct DecisionRule {
  DecisionRuleKind kind = DecisionRuleKind::simple;
  double guard_multiple = 1.0;     // guarded: the guard band w = guard_multiple x U
  double max_false_accept = 0.025; // risk: the largest probability of false acceptance
};
const char* to_string(DecisionRuleKind k);
// The rule in one sentence, for a certificate ("Decision rule: guarded acceptance, ...").
std::string rule_sentence(const DecisionRule& r);

enum class Outcome { pass, conditional, fail };
const char* to_string(Outcome o);

// A decision on one measured value against one limit.
struct Decision {
  Outcome outcome = Outcome::fail;
  double acceptance_limit = 0;  // the value must lie on the good side of this to pass
  double false_accept = 0;      // probability that the true value lies beyond the limit
};

// upper: the criterion is value <= limit (else value >= limit). U is the expanded uncertainty,
// u and dof the standard uncertainty and its degrees of freedom (for the risk rule).
//   simple:  acceptance limit = limit; pass on the good side (a value on the limit passes), fail beyond.
//   guarded: acceptance limit = limit -+ w, w = guard_multiple x U; pass up to it, conditional
//            between it and the limit (the limit itself included), fail beyond the limit.
//   risk:    acceptance limit = limit -+ t(1 - max_false_accept, dof) x u, the value at which the
//            probability that the true value lies beyond the limit is max_false_accept; pass up to
//            it, conditional up to the limit, fail beyond.
// With u = 0 every rule is the simple one.
Decision decide(const DecisionRule& rule, double value, double limit, bool upper, double u, double dof, double U);

}  // namespace fpss
