// What belongs to the stand and what to each unit: the diagnoses of several units that shared one gimbal pass, attributed.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/diagnosis/diagnosis.h"

namespace fpss {

// An effect every unit shows: the gimbal's (backlash, scale factor, non-orthogonality, settling of
// the load), the reference's time skew, or a bias, drift or roll common to every unit (the Sun
// simulator's, the stand's temperature). Its parameters are the units' mean.
struct StandEffect {
  std::string name;
  nlohmann::ordered_json params;
  std::vector<std::string> units;  // the units whose diagnoses name it (all of them)
  nlohmann::ordered_json evidence;  // each unit's parameters, and how far they agree
};

// An effect only some units show: that unit's own (its coefficients, its bias and roll as mounted,
// its clock's skew, ...). `note` says when the name is one of the gimbal's (a unit's own mount, then).
struct UnitEffect {
  std::string name;
  nlohmann::ordered_json params;
  std::string note;
};

struct JointDiagnosis {
  std::vector<StandEffect> stand_effects;
  std::vector<std::pair<std::string, std::vector<UnitEffect>>> unit_effects;  // per serial, in the units' order
  std::vector<std::string> notes;
  // {"format", "units", "stand_effects": [{name, params, units, evidence}], "unit_effects": {SERIAL: [...]}, "notes"}
  nlohmann::ordered_json to_json() const;
};

// The rule (docs/diagnosis.md, "Several units"): an effect named in the diagnosis of every unit
// (two at least) is the stand's, except a change of a unit's coefficients, which is always its own;
// the gimbal's scale factor counts as named by a unit whose diagnosis names a change of its
// coefficients (a refit contains it); an effect named in some units only is each of those units'
// own. `units`: (serial, its diagnosis).
JointDiagnosis attribute_effects(const std::vector<std::pair<std::string, Diagnosis>>& units);

// Effects the gimbal causes: seen by one unit alone they point at that unit's mount.
bool is_gimbal_effect(const std::string& name);

}  // namespace fpss
