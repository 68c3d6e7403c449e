#include "stand/session/diagnose_step.h"

#include <fmt/format.h>

#include "base/text_file.h"
#include "calib/coefficients.h"
#include "calib/diagnosis/diagnosis.h"
#include "calib/diagnosis/joint.h"
#include "stand/report/diagnosis_page.h"

namespace fpss {

DiagnoseStepResult run_diagnose_step(const SampleTable& recording, int64_t last_step, const DiagnoseStep& step,
                                     const std::filesystem::path& run_dir, int nth, const std::filesystem::path& model_file) {
  const std::filesystem::path model_path = model_file.empty() ? step.model : model_file;
  const CoefficientSet model = load_coefficients(model_path);
  DiagnosisOptions opts;
  opts.settle_s = step.settle_s;
  DiagnosisFigures figures;
  const Diagnosis d = diagnose(DiagnosisColumns::of(recording.up_to_step(last_step)), model, opts, &figures);
  const std::string stem = nth == 1 ? "GAP" : fmt::format("GAP-{}", nth);
  DiagnoseStepResult r{run_dir / (stem + ".json"), run_dir / (stem + ".html"), d.verdict, d.verdict_sentence,
                       d.cause, d.incomplete_recording()};
  nlohmann::ordered_json j = d.to_json();
  j["model"] = model_path.string();
  write_text_atomic(r.json, j.dump(2) + "\n");
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
  write_text_atomic(out, j.dump(2) + "\n");
  return out;
}

}  // namespace fpss
