// The catalogue of real-world bench effects: names and parameter keys (unit in each key), one list for the emulator and the diagnosis.
#pragma once
#include <string>
#include <vector>

namespace fpss {

struct EffectSpec {
  std::string name;
  std::vector<std::string> keys;  // every one required; none for `coefficients` (a coefficient file)
};

// In the diagnosis's order of candidates (docs/emulator.md, docs/diagnosis.md).
const std::vector<EffectSpec>& effect_specs();

}  // namespace fpss
