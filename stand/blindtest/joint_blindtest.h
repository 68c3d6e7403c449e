// The blind check of the stand-or-unit attribution: two units on one simulated gimbal pass, a stand effect for both and a unit effect on one.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace fpss {

struct JointBlindCase {
  int index = 0;
  std::string stand_effect;              // drawn: the gimbal's (every unit sees it)
  std::string unit_effect;               // drawn: one unit's own
  std::string unit_serial;               // the unit that has it
  std::vector<std::string> found_stand;  // what the attribution called the stand's
  std::vector<std::vector<std::string>> found_units;  // per unit, what it called that unit's own
  bool correct = false;  // the stand's effect, and only it, as the stand's; the unit's effect in that unit alone
};

struct JointBlindReport {
  std::vector<JointBlindCase> cases;
  double accuracy() const;
  nlohmann::ordered_json to_json() const;
  std::string to_text() const;
};

// `cases` seeded cases: units U1 (truth a-6-fpss1) and U2 (a-6-fpss2) recorded from the same
// pass of the blind check's session (blindtest_plan); the stand effect cycles through backlash,
// scale_factor, axis_nonorthogonality, settling and time_skew, the unit effect through bias,
// boresight_roll and coefficients on a unit drawn at random; each unit diagnosed against its own
// truth, then attributed (calib/diagnosis/joint.h).
JointBlindReport run_joint_blindtest(int cases, uint64_t seed, const std::function<void(const JointBlindCase&)>& progress = {});

}  // namespace fpss
