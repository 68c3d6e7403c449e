// libFuzzer harness for the stand-file reader (stand/config/stand_config.cpp through yaml_diag's
// MapReader): any text gives diagnostics with places or a stand whose numbers are finite; only
// InputError escapes.
#include <cmath>

#include "stand/config/stand_config.h"
#include "tests/support/fuzz_yaml.h"

const fpss::test::Invariants check{"stand reader"};

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace fpss;
  test::fuzz_yaml_reader(data, size, check, parse_stand, [](const StandConfig& c) {
    check(std::isfinite(c.gimbal.response_timeout_s) && c.gimbal.response_timeout_s > 0, "response timeout");
    check(std::isfinite(c.bench.profile_rate_arcsec_s) && std::isfinite(c.bench.limits.max_rate_arcsec_s), "rates");
    check(c.bench.limits.pitch_min_arcsec < c.bench.limits.pitch_max_arcsec, "pitch limits");
  });
  return 0;
}
