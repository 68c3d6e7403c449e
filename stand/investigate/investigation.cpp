// The investigation loop (stand/investigate/investigation.h).
#include "stand/investigate/investigation.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

#include "base/errors.h"
#include "base/text_file.h"
#include "stand/investigate/followup_design.h"

namespace fpss {
namespace {

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

Investigation investigate(const std::filesystem::path& first_procedure, const InvestigationOptions& opts,
                          const RunProcedure& run) {
  if (opts.max_runs < 1) throw InputError("investigate: --max-runs must be at least 1");
  std::filesystem::create_directories(opts.out_dir);
  Investigation inv;
  std::vector<std::string> recordings;
  std::filesystem::path procedure = first_procedure;
  std::string why = "the first run";
  DiagnosisOptions dopts = opts.diagnosis;
  ojson design_of_step;  // the design that chose the current run
  for (int k = 0;; ++k) {
    InvestigationRun r = run(procedure, k);
    inv.runs.push_back(r);
    ojson step{{"run", r.run_dir.string()}, {"procedure", procedure.string()}, {"why", why}};
    if (!design_of_step.is_null()) step["design"] = design_of_step;
    if (!r.completed) {
      step["outcome"] = "failed: " + r.reason;
      inv.steps.push_back(step);
      inv.stop_reason = "run_failed";
      inv.stop_sentence = fmt::format("run {} did not complete ({}); the verdict rests on the runs before it", k + 1, r.reason);
      break;
    }
    recordings.push_back(r.samples.string());
    std::vector<DiagnosisColumns> cols;
    for (const auto& path : recordings) cols.push_back(read_diagnosis_columns(path));
    Diagnosis d = diagnose(std::move(cols), opts.model, dopts);
    if (k == 0 && !(dopts.materiality_arcsec > 0)) dopts.materiality_arcsec = d.materiality_arcsec;
    predict_best_followups(d, opts.model, opts.settings, opts.bench);
    ojson gap = d.to_json();
    gap["model"] = opts.model_path;
    step["diagnosis"] = step_diagnosis(gap);
    if (k > 0) step["separated"] = separated(inv.final_json, gap);
    const double span = d.recordings.back().time_span_s[1] - d.recordings.back().time_span_s[0];
    (k == 0 ? inv.first_bench_s : inv.followup_bench_s) += span;
    step["bench_s"] = span;
    inv.steps.push_back(step);
    inv.final = std::move(d);
    inv.final_json = gap;
    write_gap_file(opts.out_dir / "GAP.json", gap);

    if (investigation_ended(inv.final)) {
      inv.stop_reason = "ended";
      inv.stop_sentence = "every candidate is named or bounded below the materiality, and no look-alikes remain";
      break;
    }
    if (k + 1 >= opts.max_runs) {
      inv.stop_reason = "max_runs";
      inv.stop_sentence = fmt::format("{} runs made (--max-runs)", k + 1);
      break;
    }
    const double left = opts.budget_ratio * inv.first_bench_s - inv.followup_bench_s;
    const double one = opts.max_followup_s > 0 ? opts.max_followup_s : 0.5 * inv.first_bench_s;
    FollowupRequest fr;
    fr.gap = gap;
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
      break;
    }
    const FollowupDesign f = design_followup(fr);
    if (!(f.found || f.useful)) {
      inv.stop_reason = "no_followup";
      inv.stop_sentence = fmt::format("nothing within {:.0f} s of bench time separates or bounds what is left",
                                      fr.max_bench_s);
      break;
    }
    procedure = opts.out_dir / (fr.name + ".yaml");
    write_text_atomic(procedure, f.procedure_text);
    design_of_step = f.to_json();
    std::vector<std::string> aims;
    for (const auto& p : f.pairs) aims.push_back(fmt::format("to tell {} from {}", p.a, p.b));
    for (const auto& b : f.bounds) aims.push_back(fmt::format("to bound {}", b.name));
    why = fmt::format("{} ({})", fmt::join(aims, ", "), fmt::join(f.moves, "; "));
  }
  inv.unbounded = open_candidates(inv.final);
  return inv;
}

ojson Investigation::to_json() const {
  ojson runs_j = ojson::array();
  for (const auto& r : runs) runs_j.push_back(r.run_dir.empty() ? r.samples.string() : r.run_dir.string());
  ojson j;
  j["runs"] = runs_j;
  j["steps"] = steps;
  // The final joint diagnosis, in GAP.json's fields.
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
