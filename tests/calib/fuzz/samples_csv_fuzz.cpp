// libFuzzer harness for the samples CSV reader (calib/samples.cpp): any input either parses into a
// table that keeps the format's promises or is an InputError; nothing else may escape.
#include <cmath>

#include "base/errors.h"
#include "calib/samples.h"
#include "tests/support/fuzz_check.h"

const fpss::test::Invariants check{"samples reader"};

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const std::string_view text = fpss::test::fuzz_text(data, size);
  fpss::SampleTable t;
  try {
    t = fpss::parse_samples_csv(text, "fuzz.csv");
  } catch (const fpss::InputError&) {
    return 0;
  }
  for (size_t i = 0; i < t.size(); ++i) {
    check(std::isfinite(t.time_s[i]) && std::isfinite(t.ref_pitch_arcsec[i]) && std::isfinite(t.ref_yaw_arcsec[i]) &&
              std::isfinite(t.counts_alpha[i]) && std::isfinite(t.counts_beta[i]),
          "a non-finite value was accepted");
    check(std::abs(t.ref_pitch_arcsec[i]) <= 648000 && std::abs(t.ref_yaw_arcsec[i]) <= 648000, "reference beyond limit");
    if (i > 0) {
      check(t.time_s[i] >= t.time_s[i - 1], "time goes backwards");
      check(t.step[i] >= t.step[i - 1], "step decreases");
    }
  }
  for (const auto& name : t.extra_names()) {
    check(t.extra_column(name).size() == t.size(), "extra column length");
    try {
      (void)t.numeric_column(name);
    } catch (const fpss::InputError&) {
    }
  }
  return 0;
}
