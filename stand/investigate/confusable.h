// The confusable and unseen cases of the active sim-to-real loop on the simulated bench: look-alikes
// and effects a first run cannot see, each investigated to the end (docs/diagnosis.md, "Investigation").
#pragma once
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace fpss {

// The kinds: skew_behind_dwells, skew_dwells_from_arrival, settling_behind_slews,
// backlash_one_side, settling_one_side, skew_single_rate, backlash_single_rate,
// temperature_sine_dwells, coefficients_narrow, and unambiguous (one catalogued effect behind
// procedures/sim_to_real.yaml).
const std::vector<std::string>& confusable_kinds();

struct ConfusableCase {
  std::string kind;
  std::string truth;  // the effect's name
  nlohmann::ordered_json truth_params = nlohmann::ordered_json::object();
  std::string main_key;                // the parameter judged within 10 %
  std::vector<std::string> causes;     // the final joint diagnosis's
  nlohmann::ordered_json fitted = nlohmann::ordered_json::object();
  bool named = false;                  // the truth among the causes
  double main_error = 0;               // relative, of main_key (named cases)
  int followups = 0;
  double followup_ratio = 0;           // follow-ups' bench time over the first run's
  std::string stop_reason;
  std::vector<std::string> still_ambiguous;
  bool success() const { return named && main_error <= 0.10; }
};

struct ConfusableReport {
  std::vector<ConfusableCase> cases;
  nlohmann::ordered_json summary() const;  // the three figures, per kind and overall
  std::string to_text() const;
};

// `per_kind` cases of each kind (seeded; of the kinds in `only` when it is not empty); each case's
// runs and files go under `work`.
ConfusableReport run_confusable_cases(int per_kind, uint64_t seed, const std::filesystem::path& work,
                                      const std::function<void(const ConfusableCase&)>& progress = {},
                                      const std::vector<std::string>& only = {});

}  // namespace fpss
