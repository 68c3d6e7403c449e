#include "calib/uncertainty.h"

#include <fmt/format.h>

#include <cmath>
#include <stdexcept>

namespace fpss {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// The continued fraction of I_x(a, b) (modified Lentz), converging for x < (a + 1) / (a + b + 2).
double beta_fraction(double a, double b, double x) {
  constexpr double tiny = 1e-300, eps = 1e-15;
  double c = 1.0, d = 1.0 - (a + b) * x / (a + 1.0);
  if (std::fabs(d) < tiny) d = tiny;
  d = 1.0 / d;
  double h = d;
  for (int m = 1; m <= 1000; ++m) {
    const double m2 = 2.0 * m;
    double aa = m * (b - m) * x / ((a + m2 - 1.0) * (a + m2));
    for (int half = 0; half < 2; ++half) {
      d = 1.0 + aa * d;
      if (std::fabs(d) < tiny) d = tiny;
      c = 1.0 + aa / c;
      if (std::fabs(c) < tiny) c = tiny;
      d = 1.0 / d;
      const double del = d * c;
      h *= del;
      if (half == 1 && std::fabs(del - 1.0) < eps) return h;
      aa = -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1.0));
    }
  }
  return h;
}

}  // namespace

nlohmann::ordered_json budget_json(const std::vector<BudgetEntry>& budget, const char* u_key) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (const BudgetEntry& e : budget) {
    nlohmann::ordered_json j{{"source", e.source}, {"type", std::string(1, e.type)}, {"sensitivity", e.sensitivity}};
    j[u_key] = e.u;
    j["dof"] = std::isfinite(e.dof) ? nlohmann::json(e.dof) : nlohmann::json(nullptr);
    out.push_back(std::move(j));
  }
  return out;
}

double incomplete_beta(double a, double b, double x) {
  if (!(a > 0) || !(b > 0) || !(x >= 0) || !(x <= 1)) throw std::domain_error("incomplete_beta: a, b > 0 and 0 <= x <= 1");
  if (x == 0 || x == 1) return x;
  const double front = std::exp(std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b) + a * std::log(x) + b * std::log1p(-x));
  if (x < (a + 1.0) / (a + b + 2.0)) return front * beta_fraction(a, b, x) / a;
  return 1.0 - front * beta_fraction(b, a, 1.0 - x) / b;
}

double student_t_cdf(double t, double nu) {
  if (!(nu > 0)) throw std::domain_error("student_t_cdf: degrees of freedom must be > 0");
  if (std::isinf(nu)) return 0.5 * std::erfc(-t / std::sqrt(2.0));
  const double tail = 0.5 * incomplete_beta(0.5 * nu, 0.5, nu / (nu + t * t));  // P(T > |t|)
  return t >= 0 ? 1.0 - tail : tail;
}

double student_t_quantile(double p, double nu) {
  if (!(p > 0 && p < 1)) throw std::domain_error("student_t_quantile: p must lie in (0, 1)");
  if (p < 0.5) return -student_t_quantile(1.0 - p, nu);
  // Bisection on the monotone CDF: slow but plain, and the CDF is exact to ~1e-15.
  double lo = 0, hi = 1;
  while (student_t_cdf(hi, nu) < p) hi *= 2;
  for (int i = 0; i < 200 && hi - lo > 1e-12 * hi; ++i) {
    const double mid = 0.5 * (lo + hi);
    (student_t_cdf(mid, nu) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

namespace {

double sum_of_squares(const std::vector<BudgetEntry>& budget) {
  double var = 0;
  for (const auto& e : budget) var += e.u * e.u;
  return var;
}

}  // namespace

double root_sum_square(const std::vector<BudgetEntry>& budget) { return std::sqrt(sum_of_squares(budget)); }

Combined combine(const std::vector<BudgetEntry>& budget) {
  Combined c;
  const double var = sum_of_squares(budget);
  c.u = std::sqrt(var);
  double ws = 0;
  for (const auto& e : budget) {
    if (std::isfinite(e.dof) && e.u > 0) ws += std::pow(e.u, 4) / e.dof;
  }
  c.dof_eff = ws > 0 ? var * var / ws : kInf;
  // The integer below, forgiving the rounding of u^4 / (u^4 / nu) for a single entry.
  const double nu = std::isfinite(c.dof_eff) ? std::max(1.0, std::floor(c.dof_eff * (1 + 1e-12))) : kInf;
  c.k = student_t_quantile(0.975, nu);
  c.U = c.k * c.u;
  return c;
}

const char* to_string(DecisionRuleKind k) {
  switch (k) {
    case DecisionRuleKind::simple: return "simple";
    case DecisionRuleKind::guarded: return "guarded";
    case DecisionRuleKind::risk: return "risk";
  }
  return "?";
}

const char* to_string(Outcome o) {
  switch (o) {
    case Outcome::pass: return "pass";
    case Outcome::conditional: return "conditional";
    case Outcome::fail: return "fail";
  }
  return "?";
}

std::string rule_sentence(const DecisionRule& r) {
  switch (r.kind) {
    case DecisionRuleKind::simple:
      return "simple acceptance (ILAC-G8): a value on the good side of its limit, or on it, passes; the "
             "uncertainty is reported but not deducted";
    case DecisionRuleKind::guarded:
      return fmt::format("guarded acceptance, guard band w = {} x U (ILAC-G8): a value passes within the acceptance "
                         "limit (the limit less w), is conditional between it and the limit, fails beyond the limit",
                         r.guard_multiple == std::floor(r.guard_multiple) ? fmt::format("{:.1f}", r.guard_multiple)
                                                                          : fmt::format("{}", r.guard_multiple));
    case DecisionRuleKind::risk:
      return fmt::format("specified risk (ILAC-G8): a value passes when the probability that the true value lies "
                         "beyond the limit is at most {} (Student's t at the value's effective degrees of freedom), is "
                         "conditional when it is larger but the value is within the limit, fails beyond the limit",
                         r.max_false_accept);
  }
  return "?";
}

Decision decide(const DecisionRule& rule, double value, double limit, bool upper, double u, double dof, double U) {
  // Work on the upper-limit form: s = how far inside the limit the value lies.
  const double sign = upper ? 1.0 : -1.0;
  double w = 0;  // guard band
  if (rule.kind == DecisionRuleKind::guarded) w = rule.guard_multiple * U;
  if (rule.kind == DecisionRuleKind::risk && u > 0) w = student_t_quantile(1.0 - rule.max_false_accept, dof) * u;
  Decision d;
  d.acceptance_limit = limit - sign * w;
  d.false_accept = u > 0 ? 1.0 - student_t_cdf(sign * (limit - value) / u, dof) : (sign * (value - limit) > 0 ? 1.0 : 0.0);
  const bool within_limit = sign * (value - limit) <= 0;
  const bool within_acceptance = sign * (value - d.acceptance_limit) <= 0;
  if (!within_limit) {
    d.outcome = Outcome::fail;
  } else if (within_acceptance || rule.kind == DecisionRuleKind::simple) {
    d.outcome = Outcome::pass;
  } else {
    d.outcome = Outcome::conditional;
  }
  return d;
}

}  // namespace fpss
