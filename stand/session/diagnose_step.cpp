#include "stand/session/diagnose_step.h"

#include <fmt/format.h>

#include "base/text_file.h"
#include "calib/coefficients.h"
#include "calib/diagnosis/diagnosis.h"
#include "calib/diagnosis/joint.h"
#include "stand/report/diagnosis_page.h"

namespace fpss {

DiagnoseStepResult run_diagnose_step(const SampleTable& recording, int64_t last_step, const DiagnoseStep& step,
                                     const std::filesystem::path& run_dir, int nth, const std::filesystem::path& model_file,
                                     const FollowupPredictor& predict) {
  const std::filesystem::path model_path = model_file.empty() ? step.model : model_file;
  const CoefficientSet model = load_coefficients(model_path);
  DiagnosisOptions opts;
  opts.settle_s = step.settle_s;
  DiagnosisFigures figures;
  Diagnosis d = diagnose(DiagnosisColumns::of(recording.up_to_step(last_step)), model, opts, &figures);
  if (predict && !d.ambiguous.empty()) predict(d, model);
  const std::string stem = nth == 1 ? "GAP" : fmt::format("GAP-{}", nth);
  DiagnoseStepResult r{.json = run_dir / (stem + ".json"), .html = run_dir / (stem + ".html"), .verdict = d.verdict,
                       .sentence = d.verdict_sentence, .cause = d.cause, .incomplete = d.incomplete_recording()};
  nlohmann::ordered_json j = d.to_json();
  j["model"] = model_path.string();
  write_gap_file(r.json, j);
  write_diagnosis_page(r.html.string(), d, figures);
  r.diagnosis = d;
  return r;
}

nlohmann::ordered_json joint_diagnosis_json(const std::vector<std::pair<std::string, Diagnosis>>& units,
                                            const std::string& run_id) {
  nlohmann::ordered_json j = attribute_effects(units).to_json();
  j["run"] = run_id;
  return j;
}

std::filesystem::path write_joint_diagnosis(const std::vector<std::pair<std::string, Diagnosis>>& units,
                                            const std::filesystem::path& run_dir, int nth, const std::string& run_id) {
  const nlohmann::ordered_json j = joint_diagnosis_json(units, run_id);
  const std::filesystem::path out = run_dir / (nth == 1 ? std::string("GAP.json") : fmt::format("GAP-{}.json", nth));
  write_gap_file(out, j);
  return out;
}

std::filesystem::path diagnose_units(const std::vector<SessionUnit>& units, int64_t last_step, const DiagnoseStep& step,
                                     const std::filesystem::path& run_dir, int nth, const std::string& run_id,
                                     spdlog::logger& log, const FollowupPredictor& predict) {
  namespace fs = std::filesystem;
  const bool several = units.size() > 1;
  std::vector<std::pair<std::string, Diagnosis>> diagnosed;
  fs::path named;
  for (const SessionUnit& u : units) {
    if (u.loss) continue;
    const auto listed = step.models.find(u.serial);
    const fs::path model = listed != step.models.end() ? listed->second : step.model;
    if (model.empty()) {
      log.warn("diagnosis: unit {} has no model in the step's models: not diagnosed", u.serial);
      continue;
    }
    DiagnoseStepResult r = run_diagnose_step(u.recorded, last_step, step, u.dir, nth, model, predict);
    log.info("{}diagnosis -> {}, {}: verdict {}, cause {}: {}", several ? "unit " + u.serial + ": " : "",
             fs::relative(r.json, run_dir).string(), r.html.filename().string(), r.verdict, r.cause, r.sentence);
    if (r.incomplete && !step.partial) {
      log.warn("diagnosis: this recording cannot tell every effect apart (GAP.json, not_observable)");
    }
    if (!several) named = r.json;
    diagnosed.emplace_back(u.serial, std::move(r.diagnosis));
  }
  if (several && !diagnosed.empty()) {
    // What is the stand's and what each unit's: the file `diagnose --run ... --out` writes.
    named = write_joint_diagnosis(diagnosed, run_dir, nth, run_id);
    log.info("stand or unit -> {}", named.filename().string());
  }
  return named;
}

}  // namespace fpss
