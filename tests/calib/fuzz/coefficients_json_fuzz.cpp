// libFuzzer harness for the JSON coefficient reader (base/json_file.cpp, calib/coefficients.cpp):
// any input is a coefficient set that survives a write/read round trip, or an InputError.
#include <cmath>
#include <cstdio>

#include "base/errors.h"
#include "base/json_file.h"
#include "calib/coefficients.h"
#include "tests/support/fuzz_check.h"

const fpss::test::Invariants check{"coefficient reader"};

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const std::string_view text = fpss::test::fuzz_text(data, size);
  fpss::CoefficientSet set;
  try {
    set = fpss::parse_coefficients(fpss::parse_json_text(text, "fuzz.json"), "fuzz.json");
  } catch (const fpss::InputError&) {
    return 0;
  }
  for (const auto* axis : {&set.alpha, &set.beta}) {
    for (double c : *axis) check(std::isfinite(c) && std::abs(c) <= fpss::kMaxAbsCoefficient, "coefficient range");
  }
  const std::string again = fpss::to_json(set).dump(1);
  fpss::CoefficientSet back;
  try {
    back = fpss::parse_coefficients(fpss::parse_json_text(again, "again.json"), "again.json");
  } catch (const fpss::InputError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    check(false, "a written set does not read back");
  }
  check(back.alpha == set.alpha && back.beta == set.beta && back.unit == set.unit && back.extra == set.extra,
        "round trip changed the set");
  return 0;
}
