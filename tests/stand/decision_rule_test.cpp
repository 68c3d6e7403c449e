// The limits file's decision_rule block: the default, each rule, and every mistake with file:line.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "base/errors.h"
#include "stand/acceptance/acceptance.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

// The shipped limits with its decision_rule block replaced by `rule` (YAML lines).
std::string with_rule(const std::string& rule) {
  std::string text = test::read_file(default_limits_path());
  const std::string shipped = "decision_rule:\n  rule: simple\n";
  const auto at = text.find(shipped);
  EXPECT_NE(at, std::string::npos);
  return text.replace(at, shipped.size(), rule);
}

// The line of `needle` in `text`, 1-based.
int line_of(const std::string& text, const std::string& needle) {
  const auto at = text.find(needle);
  EXPECT_NE(at, std::string::npos) << needle;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
}

std::string error_of(const std::string& text) {
  try {
    parse_acceptance_limits(text, "rules.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(DecisionRule, ShippedFileSaysSimpleAndAFileWithoutTheBlockIsSimpleToo) {
  EXPECT_EQ(load_acceptance_limits(default_limits_path()).decision_rule.kind, DecisionRuleKind::simple);
  const AcceptanceLimits none = parse_acceptance_limits(with_rule(""), "none.yaml");
  EXPECT_EQ(none.decision_rule.kind, DecisionRuleKind::simple);
}

TEST(DecisionRule, GuardedAndRiskWithTheirNumbers) {
  AcceptanceLimits L = parse_acceptance_limits(with_rule("decision_rule: {rule: guarded}\n"), "g.yaml");
  EXPECT_EQ(L.decision_rule.kind, DecisionRuleKind::guarded);
  EXPECT_EQ(L.decision_rule.guard_multiple, 1.0);  // w = U unless stated
  L = parse_acceptance_limits(with_rule("decision_rule:\n  rule: guarded\n  guard_multiple: 2\n"), "g.yaml");
  EXPECT_EQ(L.decision_rule.guard_multiple, 2.0);
  L = parse_acceptance_limits(with_rule("decision_rule: {rule: risk, max_false_accept: 0.01}\n"), "r.yaml");
  EXPECT_EQ(L.decision_rule.kind, DecisionRuleKind::risk);
  EXPECT_EQ(L.decision_rule.max_false_accept, 0.01);
  EXPECT_NE(rule_sentence(L.decision_rule).find("at most 0.01"), std::string::npos);
}

TEST(DecisionRule, EachMistakeNamesFileLineAndKey) {
  struct Case {
    std::string rule, needle, message;
  };
  const Case cases[] = {
      {"decision_rule:\n  rule: strict\n", "rule: strict", "decision_rule: field rule: expected one of simple, guarded, risk"},
      {"decision_rule:\n  rule: risk\n", "rule: risk", "decision_rule: missing field max_false_accept"},
      {"decision_rule:\n  rule: simple\n  guard_multiple: 2\n", "  guard_multiple: ", "guard_multiple belongs to rule guarded, not simple"},
      {"decision_rule:\n  rule: guarded\n  guard_multiple: -1\n", "  guard_multiple: ", "guard_multiple: expected a number > 0"},
      {"decision_rule:\n  rule: guarded\n  guard_multiple: 50\n", "  guard_multiple: ", "guard_multiple: at most 10"},
      {"decision_rule:\n  rule: risk\n  max_false_accept: 0.7\n", "  max_false_accept: ", "a probability below 0.5"},
      {"decision_rule:\n  rule: guarded\n  max_false_accept: 0.05\n", "  max_false_accept: ", "belongs to rule risk, not guarded"},
      {"decision_rule:\n  rule: guarded\n  guard: 2\n", "guard: 2", "guard"},
      {"decision_rule: guarded\n", "decision_rule: guarded", "decision_rule"},
  };
  for (const auto& c : cases) {
    const std::string text = with_rule(c.rule);
    const std::string m = error_of(text);
    EXPECT_NE(m.find(c.message), std::string::npos) << c.rule << "\n" << m;
    EXPECT_NE(m.find(fmt::format("rules.yaml:{}:", line_of(text, c.needle))), std::string::npos) << c.rule << "\n" << m;
  }
}

}  // namespace
}  // namespace fpss
