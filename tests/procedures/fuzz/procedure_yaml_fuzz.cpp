// libFuzzer harness for the procedure reader (procedures/procedure.cpp, yaml_diag.cpp) and the plan
// expansion (plan.cpp): any text gives diagnostics with places, or a procedure whose plan stays
// within the documented limits (docs/procedures.md, Limits). Nothing but InputError may escape.
#include <cmath>

#include "calib/errors.h"
#include "procedures/plan.h"
#include "procedures/procedure.h"
#include "tests/support/fuzz_check.h"

const fpss::test::Invariants check{"procedure reader"};

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace fpss;
  const std::string_view text = fpss::test::fuzz_text(data, size);
  Diagnostics d("fuzz.yaml");
  try {
    const Procedure p = parse_procedure(text, "fuzz.yaml", d);
    if (!d.empty()) return 0;
    EngineSettings b;
    Diagnostics pd("fuzz.yaml");
    const Plan plan = expand(p, b, pd);
    check(plan.points <= kMaxPlanPoints, "a plan beyond kMaxPlanPoints");
    check(std::isfinite(plan.estimated_s) && plan.estimated_s >= 0, "a non-finite or negative estimate");
    (void)format_plan(p, plan, b);
  } catch (const InputError&) {
  }
  for (const auto& e : d.all()) check(e.file == "fuzz.yaml" && !e.message.empty(), "a diagnostic without a place");
  return 0;
}
