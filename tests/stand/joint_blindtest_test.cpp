// Stand or unit: the attribution rule on hand-made diagnoses, and its blind check on 100 seeded
// two-unit cases (a stand effect for both, a unit effect on one) of the simulated bench.
#include "stand/blindtest/joint_blindtest.h"

#include <gtest/gtest.h>

#include <iostream>
#include <set>

#include "calib/diagnosis/joint.h"

namespace fpss {
namespace {

Diagnosis with_causes(std::vector<std::pair<std::string, double>> causes) {
  Diagnosis d;
  for (const auto& [name, v] : causes) {
    EffectResult e;
    e.name = name;
    e.params = {{"value", v}};
    d.causes.push_back(e);
  }
  if (!d.causes.empty()) d.cause = d.causes.front().name;
  return d;
}

std::vector<std::string> stand_names(const JointDiagnosis& j) {
  std::vector<std::string> n;
  for (const auto& s : j.stand_effects) n.push_back(s.name);
  return n;
}

TEST(JointAttribution, WhatEveryUnitShowsIsTheStandsWhatOneShowsIsItsOwn) {
  const JointDiagnosis j = attribute_effects({{"U1", with_causes({{"backlash", 3.0}})},
                                              {"U2", with_causes({{"bias", 2.0}, {"backlash", 3.2}})},
                                              {"U3", with_causes({{"backlash", 2.9}})}});
  EXPECT_EQ(stand_names(j), std::vector<std::string>{"backlash"});
  EXPECT_NEAR(j.stand_effects.front().params["value"].get<double>(), 3.0333, 1e-3);
  EXPECT_EQ(j.stand_effects.front().units.size(), 3u);
  ASSERT_EQ(j.unit_effects.size(), 3u);
  EXPECT_TRUE(j.unit_effects[0].second.empty());
  ASSERT_EQ(j.unit_effects[1].second.size(), 1u);
  EXPECT_EQ(j.unit_effects[1].second.front().name, "bias");
  EXPECT_TRUE(j.unit_effects[2].second.empty());
}

TEST(JointAttribution, ChangedCoefficientsAreAlwaysTheUnitsAndMayHoldTheGimbalsScale) {
  // Both units changed: still each one's own.
  JointDiagnosis j = attribute_effects({{"U1", with_causes({{"coefficients", 1}})}, {"U2", with_causes({{"coefficients", 1}})}});
  EXPECT_TRUE(j.stand_effects.empty());
  EXPECT_EQ(j.unit_effects[0].second.size(), 1u);
  // The scale factor inside U1's refit: the stand's, its size from U2 alone.
  j = attribute_effects({{"U1", with_causes({{"coefficients", 1}})}, {"U2", with_causes({{"scale_factor", 500}})}});
  EXPECT_EQ(stand_names(j), std::vector<std::string>{"scale_factor"});
  EXPECT_EQ(j.stand_effects.front().evidence["absorbed_by_coefficients"], nlohmann::ordered_json::array({"U1"}));
  EXPECT_EQ(j.unit_effects[0].second.front().name, "coefficients");
  EXPECT_TRUE(j.unit_effects[1].second.empty());
  // A bias is no part of the gimbal: one unit's bias stays its own beside another's refit.
  j = attribute_effects({{"U1", with_causes({{"coefficients", 1}})}, {"U2", with_causes({{"bias", 2}})}});
  EXPECT_TRUE(j.stand_effects.empty());
}

TEST(JointAttribution, AGimbalEffectSeenByOneUnitPointsAtItsMount) {
  const JointDiagnosis j = attribute_effects({{"U1", with_causes({{"backlash", 3.0}})}, {"U2", with_causes({})}});
  EXPECT_TRUE(j.stand_effects.empty());
  ASSERT_EQ(j.unit_effects[0].second.size(), 1u);
  EXPECT_NE(j.unit_effects[0].second.front().note.find("mount"), std::string::npos);
  // One unit alone: nothing to tell apart, said so.
  EXPECT_FALSE(attribute_effects({{"U1", with_causes({{"backlash", 3.0}})}}).notes.empty());
}

// The figure: right in at least 95 % of at least 100 seeded cases.
TEST(JointBlindTest, StandOrUnitIsRightInAtLeast95PercentOf100Cases) {
  const JointBlindReport rep = run_joint_blindtest(100, 1);
  ASSERT_EQ(rep.cases.size(), 100u);
  std::cout << rep.to_text();
  EXPECT_GE(rep.accuracy(), 0.95);
  // Every class drawn.
  std::set<std::string> stand, unit;
  for (const auto& c : rep.cases) {
    stand.insert(c.stand_effect);
    unit.insert(c.unit_effect);
  }
  EXPECT_EQ(stand.size(), 5u);
  EXPECT_EQ(unit.size(), 3u);
}

}  // namespace
}  // namespace fpss
