// The experimenter's loop (`fpss-stand investigate`): run a procedure, diagnose, and while
// look-alikes stay or a candidate is neither named nor bounded, design the follow-up, run it and
// diagnose every recording jointly; INVESTIGATION.json says each step and the final verdict.
#pragma once
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "calib/diagnosis/diagnosis.h"
#include "fixtures/bench.h"
#include "procedures/events.h"
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
  StopCause cause = StopCause::none;  // why it stopped when it did not complete
  std::string reason;                 // why it did not complete
  int64_t points_done = -1;           // points recorded; -1: not known (the recording says)
  std::string acceptance;             // an accept run's verdict (pass | conditional | fail); "" none
  // The session could not start: a device or its link failed before the run began (no run folder).
  bool device_failed_to_start = false;
  std::string outcome() const;        // run.json's: completed | failed | interrupted
};

// What a run that did not complete means for the loop. The run's own judgement of the unit (a
// check's limits, a fit, a diagnose step) leaves a good recording: diagnose it and go on. A device,
// link or storage failure, or a stop the operator asked for, ends the loop.
enum class RunStopKind { completed, unit_judged, device_fault, stopped };
RunStopKind classify_stop(const InvestigationRun& r);
// "check failed: pitch max |residual| ...", "device fault: gimbal_fault: ...".
std::string describe_stop(const InvestigationRun& r);

// Runs a procedure file on the bench (the stand's session, or an in-process simulation for the
// benchmark); `index` 0 is the first run.
using RunProcedure = std::function<InvestigationRun(const std::filesystem::path& procedure, int index)>;

struct Investigation {
  std::vector<InvestigationRun> runs;
  nlohmann::ordered_json steps = nlohmann::ordered_json::array();
  Diagnosis final;                      // the joint diagnosis of every recording (when diagnosed())
  nlohmann::ordered_json final_json;    // its GAP.json; null while no diagnosis was made
  // ended | max_runs | budget | no_followup | device_fault | run_stopped | not_diagnosable
  std::string stop_reason;
  std::string stop_sentence;
  std::string no_diagnosis;             // why no diagnosis was made ("" when one was)
  std::vector<std::string> unbounded;   // candidates neither named nor bounded at the end
  double first_bench_s = 0, followup_bench_s = 0;
  bool ended() const { return stop_reason == "ended"; }
  bool diagnosed() const { return !final_json.is_null(); }
  // The loop stopped at a run that did not finish and could not be gone on from (exit 1).
  bool stopped_by_a_run() const;
  nlohmann::ordered_json to_json() const;  // INVESTIGATION.json
};

// True when every catalogued candidate is named or bounded and no look-alikes remain.
bool investigation_ended(const Diagnosis& d);

// `first_procedure` is run as run 1, unless `first_run` is given: a run made earlier (`investigate
// --from`), whose recording is the first diagnosed and whose procedure is recorded as `first_procedure`.
Investigation investigate(const std::filesystem::path& first_procedure, const InvestigationOptions& opts,
                          const RunProcedure& run, const std::optional<InvestigationRun>& first_run = std::nullopt);

}  // namespace fpss
