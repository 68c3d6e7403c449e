// libFuzzer harness for the stand-file reader (stand/config/stand_config.cpp through yaml_diag's
// MapReader): any text gives diagnostics or a stand whose numbers are finite; only InputError escapes.
#include <cmath>

#include "calib/errors.h"
#include "stand/config/stand_config.h"
#include "tests/support/fuzz_check.h"

const fpss::test::Invariants check{"stand reader"};

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace fpss;
  const std::string_view text = fpss::test::fuzz_text(data, size);
  Diagnostics d("fuzz.yaml");
  try {
    const StandConfig c = parse_stand(text, "fuzz.yaml", d);
    if (d.empty()) {
      check(std::isfinite(c.gimbal.response_timeout_s) && c.gimbal.response_timeout_s > 0, "response timeout");
      check(std::isfinite(c.bench.profile_rate_arcsec_s) && std::isfinite(c.bench.limits.max_rate_arcsec_s),
            "rates");
      check(c.bench.limits.pitch_min_arcsec < c.bench.limits.pitch_max_arcsec, "pitch limits");
    }
  } catch (const InputError&) {
  }
  return 0;
}
