// The investigation loop (stand/investigate/investigation.h).
#include "stand/investigate/investigation.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <map>
#include <utility>

#include "base/errors.h"
#include "base/text_file.h"
#include "stand/investigate/followup_design.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using ojson = nlohmann::ordered_json;

std::vector<std::string> open_candidates(const Diagnosis& d) {
  std::vector<std::string> open;
  for (const auto& c : d.candidates) {
    const std::string s = c.value("status", "");
    if (s != "named" && s != "bounded") open.push_back(c.value("name", ""));
  }
  return open;
}

// What a diagnosis says in a step of the record.
ojson step_diagnosis(const ojson& gap) {
  ojson sets = ojson::array();
  for (const auto& a : gap["ambiguous"]) sets.push_back(a["members"]);
  ojson status = ojson::object();
  for (const auto& c : gap["candidates"]) status[c["name"].get<std::string>()] = c["status"];
  return {{"verdict", gap["verdict"]},       {"cause", gap["cause"]},
          {"causes", gap["causes"]},         {"ambiguous", sets},
          {"candidates", status},            {"gap_before_arcsec", gap["gap_before_arcsec"]},
          {"gap_after_arcsec", gap["gap_after_all_arcsec"]}, {"noise_floor_arcsec", gap["noise_floor_arcsec"]}};
}

// What a follow-up settled: the look-alike sets gone, the candidates newly named or bounded.
ojson separated(const ojson& before, const ojson& after) {
  ojson out = ojson::array();
  for (const auto& a : before["ambiguous"]) {
    bool still = false;
    for (const auto& b : after["ambiguous"]) still = still || b["members"] == a["members"];
    if (!still) out.push_back(fmt::format("{}: told apart", fmt::join(a["members"].get<std::vector<std::string>>(), " / ")));
  }
  std::map<std::string, std::string> was;
  for (const auto& c : before["candidates"]) was[c["name"].get<std::string>()] = c["status"].get<std::string>();
  for (const auto& c : after["candidates"]) {
    const std::string n = c["name"].get<std::string>(), s = c["status"].get<std::string>();
    if ((s == "named" || s == "bounded") && was[n] != s) out.push_back(fmt::format("{}: {} (was {})", n, s, was[n]));
  }
  return out;
}

}  // namespace

bool investigation_ended(const Diagnosis& d) { return d.ambiguous.empty() && open_candidates(d).empty(); }

std::string InvestigationRun::outcome() const {
  if (completed) return "completed";
  return cause == StopCause::interrupted || cause == StopCause::aborted ? "interrupted" : "failed";
}

RunStopKind classify_stop(const InvestigationRun& r) {
  if (r.completed) return RunStopKind::completed;
  if (r.device_failed_to_start) return RunStopKind::device_fault;
  switch (r.cause) {
    case StopCause::check_failed:
    case StopCause::calibration_failed:
    case StopCause::diagnosis_failed:
      return RunStopKind::unit_judged;
    case StopCause::sensor_invalid:
    case StopCause::sensor_timeout:
    case StopCause::gimbal_fault:
    case StopCause::commanded_elsewhere:
    case StopCause::storage:
    case StopCause::unsafe:
      return RunStopKind::device_fault;
    default:
      return RunStopKind::stopped;
  }
}

std::string describe_stop(const InvestigationRun& r) {
  const auto with = [&](const std::string& what) { return r.reason.empty() ? what : what + ": " + r.reason; };
  if (r.completed) return r.acceptance == "fail" ? "completed, acceptance failed" : "completed";
  switch (r.cause) {
    case StopCause::check_failed: return with("check failed");
    case StopCause::calibration_failed: return with("calibration failed");
    case StopCause::diagnosis_failed: return with("diagnose step failed");
    case StopCause::interrupted: return with("interrupted");
    case StopCause::aborted: return with("aborted");
    default: break;
  }
  if (r.device_failed_to_start) return with("device fault (the bench could not be reached)");
  if (classify_stop(r) == RunStopKind::device_fault) return with(fmt::format("device fault ({})", to_string(r.cause)));
  return with(fmt::format("stopped ({})", to_string(r.cause)));
}

bool Investigation::stopped_by_a_run() const {
  return stop_reason == "device_fault" || stop_reason == "run_stopped" || stop_reason == "not_diagnosable";
}

namespace {

// The loop's state between runs.
struct LoopState {
  std::vector<std::string> recordings;
  DiagnosisOptions dopts;
};

std::string ordinal_run(size_t k) { return k == 0 ? "the first run" : fmt::format("run {}", k + 1); }

// Ends the loop at run k (0-based) that gives nothing more to go on from.
void stop_at_run(Investigation& inv, size_t k, const std::string& reason, const std::string& sentence) {
  inv.stop_reason = reason;
  inv.stop_sentence = fmt::format("{} {}", ordinal_run(k), sentence);
}

// The recordings so far, this run's included, diagnosed jointly into `inv` and `step`; false (the
// recording left out, `step` saying why) when the diagnosis could not be made.
bool diagnose_recordings(Investigation& inv, LoopState& st, const InvestigationRun& r, size_t k,
                         const InvestigationOptions& opts, ojson& step) {
  st.recordings.push_back(r.samples.string());
  Diagnosis d;
  try {
    std::vector<DiagnosisColumns> cols;
    for (const auto& path : st.recordings) cols.push_back(read_diagnosis_columns(path));
    d = diagnose(std::move(cols), opts.model, st.dopts);
  } catch (const std::exception& e) {
    st.recordings.pop_back();
    step["no_diagnosis"] = e.what();
    return false;
  }
  if (k == 0 && !(st.dopts.materiality_arcsec > 0)) st.dopts.materiality_arcsec = d.materiality_arcsec;
  predict_best_followups(d, opts.model, opts.settings, opts.bench);
  ojson gap = d.to_json();
  gap["model"] = opts.model_path;
  step["diagnosis"] = step_diagnosis(gap);
  if (inv.diagnosed()) step["separated"] = separated(inv.final_json, gap);
  const double span = d.recordings.back().time_span_s[1] - d.recordings.back().time_span_s[0];
  (k == 0 ? inv.first_bench_s : inv.followup_bench_s) += span;
  step["bench_s"] = span;
  inv.final = std::move(d);
  inv.final_json = gap;
  write_gap_file(opts.out_dir / "GAP.json", gap);
  return true;
}

// Takes run k's outcome into the record and the diagnosis; true when the loop may go on.
bool take_run(Investigation& inv, LoopState& st, const InvestigationRun& r, size_t k, const InvestigationOptions& opts,
              ojson& step) {
  const RunStopKind kind = classify_stop(r);
  step["outcome"] = r.outcome();
  if (kind != RunStopKind::completed) step["stop_cause"] = to_string(r.cause);
  if (!r.acceptance.empty()) step["acceptance"] = r.acceptance;
  if (kind != RunStopKind::completed || !r.acceptance.empty()) step["stop"] = describe_stop(r);
  if (kind == RunStopKind::device_fault) {
    // The device was failing: what it recorded last is not evidence of the unit's effects.
    const std::string when = r.points_done == 0 ? "before any point was recorded"
                             : r.points_done > 0 ? fmt::format("after {} points", r.points_done)
                                                 : "";
    stop_at_run(inv, k, "device_fault",
                fmt::format("stopped at a device fault {}({}); a device fault ends the investigation{}",
                            when.empty() ? "" : when + " ", describe_stop(r),
                            r.points_done == 0 ? "" : " and its recording is not diagnosed"));
    return false;
  }
  if (r.points_done == 0) {
    stop_at_run(inv, k, kind == RunStopKind::stopped ? "run_stopped" : "not_diagnosable",
                fmt::format("recorded no point ({})", describe_stop(r)));
    return false;
  }
  if (!diagnose_recordings(inv, st, r, k, opts, step)) {
    stop_at_run(inv, k, "not_diagnosable",
                fmt::format("could not be diagnosed ({}): {}", describe_stop(r), step["no_diagnosis"].get<std::string>()));
    return false;
  }
  if (kind == RunStopKind::stopped) {
    stop_at_run(inv, k, "run_stopped",
                fmt::format("did not finish ({}); its recording is diagnosed, and the investigation ends there",
                            describe_stop(r)));
    return false;
  }
  return true;
}

// Why no diagnosis was made, when none was: the first run's stop, in the words the output prints.
std::string why_no_diagnosis(const Investigation& inv) {
  if (inv.runs.empty()) return "no run was made";
  const InvestigationRun& r = inv.runs.front();
  const ojson& step = inv.steps.front();
  if (classify_stop(r) == RunStopKind::device_fault || r.points_done == 0) {
    return fmt::format("the first run {} {}", r.completed ? "completed" : "failed",
                       r.points_done == 0 ? fmt::format("before any point was recorded ({})", describe_stop(r))
                                          : fmt::format("and its recording is not diagnosed ({})", describe_stop(r)));
  }
  return fmt::format("the first run's recording could not be diagnosed ({}): {}", describe_stop(r),
                     step.value("no_diagnosis", std::string("no reason given")));
}

// The follow-up after run k, written to out_dir; nullopt (the loop stopped, `inv` saying why) when
// there is none to make.
std::optional<std::pair<fs::path, FollowupDesign>> next_followup(Investigation& inv, size_t k,
                                                                 const InvestigationOptions& opts) {
  if (investigation_ended(inv.final)) {
    inv.stop_reason = "ended";
    inv.stop_sentence = "every candidate is named or bounded below the materiality, and no look-alikes remain";
    return std::nullopt;
  }
  if (static_cast<int>(k) + 1 >= opts.max_runs) {
    inv.stop_reason = "max_runs";
    inv.stop_sentence = fmt::format("{} runs made (--max-runs)", k + 1);
    return std::nullopt;
  }
  const double left = opts.budget_ratio * inv.first_bench_s - inv.followup_bench_s;
  const double one = opts.max_followup_s > 0 ? opts.max_followup_s : 0.5 * inv.first_bench_s;
  FollowupRequest fr;
  fr.gap = inv.final_json;
  fr.model = opts.model;
  fr.settings = opts.settings;
  fr.bench = opts.bench;
  fr.discriminate = true;
  fr.observe = true;
  fr.max_bench_s = std::min(one, left);
  fr.name = fmt::format("FOLLOWUP-{}", k + 1);
  if (!(fr.max_bench_s > 1.0)) {
    inv.stop_reason = "budget";
    inv.stop_sentence = fmt::format("the bench-time budget is spent ({:.0f} s of follow-ups against {:.0f} s allowed)",
                                    inv.followup_bench_s, opts.budget_ratio * inv.first_bench_s);
    return std::nullopt;
  }
  FollowupDesign f = design_followup(fr);
  if (!(f.found || f.useful)) {
    inv.stop_reason = "no_followup";
    inv.stop_sentence =
        fmt::format("nothing within {:.0f} s of bench time separates or bounds what is left", fr.max_bench_s);
    return std::nullopt;
  }
  const fs::path procedure = opts.out_dir / (fr.name + ".yaml");
  write_text_atomic(procedure, f.procedure_text);
  return std::make_pair(procedure, std::move(f));
}

}  // namespace

Investigation investigate(const fs::path& first_procedure, const InvestigationOptions& opts, const RunProcedure& run,
                          const std::optional<InvestigationRun>& first_run) {
  if (opts.max_runs < 1) throw InputError("investigate: --max-runs must be at least 1");
  fs::create_directories(opts.out_dir);
  Investigation inv;
  LoopState st{.recordings = {}, .dopts = opts.diagnosis};
  fs::path procedure = first_procedure;
  std::string why = first_run ? "a run made earlier (--from)" : "the first run";
  ojson design_of_step;  // the design that chose the current run
  for (size_t k = 0;; ++k) {
    const InvestigationRun r = k == 0 && first_run ? *first_run : run(procedure, static_cast<int>(k));
    inv.runs.push_back(r);
    ojson step{{"run", r.run_dir.string()}, {"procedure", procedure.string()}, {"why", why}};
    if (!design_of_step.is_null()) step["design"] = design_of_step;
    const bool go_on = take_run(inv, st, r, k, opts, step);
    inv.steps.push_back(step);
    if (!go_on) break;
    auto next = next_followup(inv, k, opts);
    if (!next) break;
    procedure = next->first;
    const FollowupDesign& f = next->second;
    design_of_step = f.to_json();
    std::vector<std::string> aims;
    for (const auto& p : f.pairs) aims.push_back(fmt::format("to tell {} from {}", p.a, p.b));
    for (const auto& b : f.bounds) aims.push_back(fmt::format("to bound {}", b.name));
    why = fmt::format("{} ({})", fmt::join(aims, ", "), fmt::join(f.moves, "; "));
  }
  if (inv.diagnosed()) inv.unbounded = open_candidates(inv.final);
  else inv.no_diagnosis = why_no_diagnosis(inv);
  return inv;
}

ojson Investigation::to_json() const {
  ojson runs_j = ojson::array();
  for (const auto& r : runs) runs_j.push_back(r.run_dir.empty() ? r.samples.string() : r.run_dir.string());
  ojson j;
  j["runs"] = runs_j;
  j["steps"] = steps;
  j["diagnosed"] = diagnosed();
  if (!diagnosed()) j["no_diagnosis"] = no_diagnosis;
  // The final joint diagnosis, in GAP.json's fields (none, no verdict, when no diagnosis was made).
  for (const char* key : {"verdict", "verdict_sentence", "cause", "causes", "effects", "ambiguous", "candidates",
                          "not_observable", "recordings", "materiality_arcsec", "noise_floor_arcsec"}) {
    if (final_json.contains(key)) j[key] = final_json[key];
  }
  j["ended"] = ended();
  j["stop_reason"] = stop_reason;
  j["stop_sentence"] = stop_sentence;
  j["unbounded"] = unbounded;
  j["bench_time_s"] = {{"first", first_bench_s},
                       {"followups", followup_bench_s},
                       {"followups_ratio", first_bench_s > 0 ? followup_bench_s / first_bench_s : 0.0}};
  return j;
}

}  // namespace fpss
