// Uncertainty budgets: the incomplete beta and Student's t against tabulated values, the
// Welch-Satterthwaite combination, and each zone of each decision rule.
#include "calib/uncertainty.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace fpss {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(IncompleteBeta, ClosedForms) {
  for (double x : {0.0, 0.1, 0.37, 0.5, 0.9, 1.0}) {
    EXPECT_NEAR(incomplete_beta(1, 1, x), x, 1e-14);
    EXPECT_NEAR(incomplete_beta(3, 1, x), x * x * x, 1e-14);
    EXPECT_NEAR(incomplete_beta(1, 4, x), 1 - std::pow(1 - x, 4), 1e-14);
  }
  // I_x(1/2, 1/2) = (2/pi) asin(sqrt x): the arcsine law.
  EXPECT_NEAR(incomplete_beta(0.5, 0.5, 0.3), 2 / M_PI * std::asin(std::sqrt(0.3)), 1e-13);
  EXPECT_THROW(incomplete_beta(0, 1, 0.5), std::domain_error);
}

TEST(StudentT, QuantilesMatchTheTables) {
  // Tabulated 97.5 % points (e.g. GUM Table G.2; NIST/SEMATECH e-Handbook 1.3.6.7.2).
  EXPECT_NEAR(student_t_quantile(0.975, 1), 12.7062, 1e-4);
  EXPECT_NEAR(student_t_quantile(0.975, 2), 4.3027, 1e-4);
  EXPECT_NEAR(student_t_quantile(0.975, 10), 2.2281, 1e-4);
  EXPECT_NEAR(student_t_quantile(0.975, 30), 2.0423, 1e-4);
  EXPECT_NEAR(student_t_quantile(0.975, kInf), 1.95996, 1e-5);
  EXPECT_NEAR(student_t_quantile(0.95, 5), 2.0150, 1e-4);
  EXPECT_NEAR(student_t_quantile(0.025, 10), -2.2281, 1e-4);
  EXPECT_NEAR(student_t_cdf(0, 7), 0.5, 1e-15);
  // A large nu approaches the normal.
  EXPECT_NEAR(student_t_quantile(0.975, 1e7), 1.95996, 1e-5);
  EXPECT_THROW(student_t_quantile(1.0, 3), std::domain_error);
}

TEST(Combine, RootSumOfSquaresAndWelchSatterthwaite) {
  Combined c = combine({{"noise", 'A', 1, 3, 4}, {"quantisation", 'B', 1, 4, kInf}});
  EXPECT_DOUBLE_EQ(c.u, 5);
  EXPECT_NEAR(c.dof_eff, 625.0 / (81.0 / 4), 1e-12);  // 30.86
  EXPECT_NEAR(c.k, student_t_quantile(0.975, 30), 1e-12);  // at the integer below
  EXPECT_DOUBLE_EQ(c.U, c.k * 5);
  c = combine({{"a", 'A', 1, 1, 9}, {"b", 'A', 1, 1, 9}});
  EXPECT_NEAR(c.dof_eff, 18, 1e-12);
  // One entry: its own degrees of freedom, and k at them (not at the integer below a rounding).
  c = combine({{"a", 'A', 1, 0.0123, 48}});
  EXPECT_NEAR(c.dof_eff, 48, 1e-9);
  EXPECT_DOUBLE_EQ(c.k, student_t_quantile(0.975, 48));
  c = combine({{"b", 'B', 1, 2, kInf}});
  EXPECT_TRUE(std::isinf(c.dof_eff));
  EXPECT_NEAR(c.k, 1.95996, 1e-5);
  c = combine({});
  EXPECT_EQ(c.u, 0);
  EXPECT_EQ(c.U, 0);
}

// value <= 5 with U = 1 (u = 0.5 at 30 dof, k about 2).
Outcome upper(const DecisionRule& r, double v) { return decide(r, v, 5.0, true, 0.5, 30, 1.0).outcome; }
Outcome lower(const DecisionRule& r, double v) { return decide(r, v, 5.0, false, 0.5, 30, 1.0).outcome; }

TEST(Decide, SimpleComparesWithTheLimitOnly) {
  const DecisionRule s;
  EXPECT_EQ(upper(s, 4.9), Outcome::pass);
  EXPECT_EQ(upper(s, 5.0), Outcome::pass);  // on the limit passes, as before the rules
  EXPECT_EQ(upper(s, 5.01), Outcome::fail);
  EXPECT_EQ(lower(s, 5.0), Outcome::pass);
  EXPECT_EQ(lower(s, 4.99), Outcome::fail);
  EXPECT_EQ(decide(s, 4.9, 5.0, true, 0.5, 30, 1.0).acceptance_limit, 5.0);
}

TEST(Decide, GuardedHasAConditionalZoneBetweenTheAcceptanceLimitAndTheLimit) {
  const DecisionRule g{DecisionRuleKind::guarded, 1.0, 0};
  EXPECT_DOUBLE_EQ(decide(g, 3, 5.0, true, 0.5, 30, 1.0).acceptance_limit, 4.0);
  EXPECT_EQ(upper(g, 3.9), Outcome::pass);
  EXPECT_EQ(upper(g, 4.0), Outcome::pass);
  EXPECT_EQ(upper(g, 4.01), Outcome::conditional);
  EXPECT_EQ(upper(g, 5.0), Outcome::conditional);
  EXPECT_EQ(upper(g, 5.01), Outcome::fail);
  EXPECT_DOUBLE_EQ(decide(g, 3, 5.0, false, 0.5, 30, 1.0).acceptance_limit, 6.0);
  EXPECT_EQ(lower(g, 6.1), Outcome::pass);
  EXPECT_EQ(lower(g, 5.5), Outcome::conditional);
  EXPECT_EQ(lower(g, 4.9), Outcome::fail);
  const DecisionRule g2{DecisionRuleKind::guarded, 2.0, 0};
  EXPECT_EQ(upper(g2, 3.5), Outcome::conditional);
  EXPECT_EQ(upper(g2, 3.0), Outcome::pass);
  // No uncertainty: no guard band.
  EXPECT_EQ(decide(g, 5.0, 5.0, true, 0, kInf, 0).outcome, Outcome::pass);
}

TEST(Decide, RiskPassesWhileTheFalseAcceptanceProbabilityIsSmallEnough) {
  const DecisionRule r{DecisionRuleKind::risk, 1.0, 0.025};
  const Decision at = decide(r, 0, 5.0, true, 0.5, 30, 1.0);
  // The acceptance limit is where P(true > L) = 2.5 %: L - t(0.975, 30) u.
  EXPECT_NEAR(at.acceptance_limit, 5.0 - 2.0423 * 0.5, 1e-4);
  EXPECT_EQ(upper(r, 3.9), Outcome::pass);
  EXPECT_EQ(upper(r, 4.0), Outcome::conditional);
  EXPECT_EQ(upper(r, 5.0), Outcome::conditional);
  EXPECT_EQ(upper(r, 5.2), Outcome::fail);
  const Decision d = decide(r, 5.0, 5.0, true, 0.5, 30, 1.0);
  EXPECT_NEAR(d.false_accept, 0.5, 1e-12);
  EXPECT_NEAR(decide(r, 5.0 - 2.0423 * 0.5, 5.0, true, 0.5, 30, 1.0).false_accept, 0.025, 1e-5);
  EXPECT_EQ(lower(r, 6.1), Outcome::pass);
  EXPECT_EQ(lower(r, 5.5), Outcome::conditional);
}

}  // namespace
}  // namespace fpss
