#include "stand/session/diagnose_step.h"

#include <fmt/format.h>

#include "base/text_file.h"
#include "calib/coefficients.h"
#include "calib/diagnosis/diagnosis.h"
#include "stand/report/diagnosis_page.h"

namespace fpss {

DiagnoseStepResult run_diagnose_step(const SampleTable& recording, int64_t last_step, const DiagnoseStep& step,
                                     const std::filesystem::path& run_dir, int nth) {
  const CoefficientSet model = load_coefficients(step.model);
  DiagnosisOptions opts;
  opts.settle_s = step.settle_s;
  DiagnosisFigures figures;
  const Diagnosis d = diagnose(DiagnosisColumns::of(recording.up_to_step(last_step)), model, opts, &figures);
  const std::string stem = nth == 1 ? "GAP" : fmt::format("GAP-{}", nth);
  DiagnoseStepResult r{run_dir / (stem + ".json"), run_dir / (stem + ".html"), d.verdict, d.verdict_sentence,
                       d.cause, d.incomplete_recording()};
  nlohmann::ordered_json j = d.to_json();
  j["model"] = step.model.string();
  write_text_atomic(r.json, j.dump(2) + "\n");
  write_diagnosis_page(r.html.string(), d, figures);
  return r;
}

}  // namespace fpss
