// The experimenter's loop (`fpss-stand investigate`): run a procedure, diagnose, and while
// look-alikes stay or a candidate is neither named nor bounded, design the follow-up, run it and
// diagnose every recording jointly; INVESTIGATION.json says each step and the final verdict.
#pragma once
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "calib/diagnosis/diagnosis.h"
#include "fixtures/bench.h"
#include "procedures/settings.h"

namespace fpss {

struct InvestigationOptions {
  CoefficientSet model;
  std::string model_path;           // as given, for the record
  int max_runs = 3;                 // the first run and at most two follow-ups
  double budget_ratio = 1.0;        // the follow-ups' total bench time, times the first run's
  double max_followup_s = 0;        // one follow-up's; 0: half the first run's
  EngineSettings settings;          // the designer's bench: the stand's, or the emulated one's
  BenchConfig bench;
  DiagnosisOptions diagnosis;       // its materiality_arcsec 0: the first diagnosis's (one dwell mean's noise)
  std::filesystem::path out_dir;    // FOLLOWUP-k.yaml, GAP.json, GAP.html, INVESTIGATION.json
};

// One run of the loop, as the runner reports it.
struct InvestigationRun {
  std::filesystem::path run_dir;  // the run folder ("" for an in-process run)
  std::filesystem::path samples;  // its recording
  bool completed = false;
  std::string reason;             // why it did not complete
};

// Runs a procedure file on the bench (the stand's session, or an in-process simulation for the
// benchmark); `index` 0 is the first run.
using RunProcedure = std::function<InvestigationRun(const std::filesystem::path& procedure, int index)>;

struct Investigation {
  std::vector<InvestigationRun> runs;
  nlohmann::ordered_json steps = nlohmann::ordered_json::array();
  Diagnosis final;                      // the joint diagnosis of every recording
  nlohmann::ordered_json final_json;    // its GAP.json
  std::string stop_reason;              // ended | max_runs | budget | no_followup | run_failed
  std::string stop_sentence;
  std::vector<std::string> unbounded;   // candidates neither named nor bounded at the end
  double first_bench_s = 0, followup_bench_s = 0;
  bool ended() const { return stop_reason == "ended"; }
  nlohmann::ordered_json to_json() const;  // INVESTIGATION.json
};

// True when every catalogued candidate is named or bounded and no look-alikes remain.
bool investigation_ended(const Diagnosis& d);

Investigation investigate(const std::filesystem::path& first_procedure, const InvestigationOptions& opts,
                          const RunProcedure& run);

}  // namespace fpss
