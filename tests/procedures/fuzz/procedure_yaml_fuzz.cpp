// libFuzzer harness for the procedure reader (procedures/procedure.cpp, yaml_diag.cpp) and the plan
// expansion (plan.cpp): any text gives diagnostics with places, or a procedure whose plan stays
// within the documented limits (docs/procedures.md, Limits). Nothing but InputError may escape.
#include <cmath>

#include "procedures/plan.h"
#include "procedures/procedure.h"
#include "tests/support/fuzz_yaml.h"

const fpss::test::Invariants check{"procedure reader"};

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace fpss;
  test::fuzz_yaml_reader(data, size, check, parse_procedure, [](const Procedure& p) {
    EngineSettings b;
    Diagnostics pd(test::kFuzzFile);
    const Plan plan = expand(p, b, pd);
    check(plan.points <= kMaxPlanPoints, "a plan beyond kMaxPlanPoints");
    check(std::isfinite(plan.estimated_s) && plan.estimated_s >= 0, "a non-finite or negative estimate");
    (void)format_plan(p, plan, b);
  });
  return 0;
}
