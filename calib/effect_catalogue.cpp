#include "calib/effect_catalogue.h"

namespace fpss {

const std::vector<EffectSpec>& effect_specs() {
  static const std::vector<EffectSpec> k = {
      {"bias", {"pitch_arcsec", "yaw_arcsec"}},
      {"drift", {"pitch_arcsec_per_s", "yaw_arcsec_per_s"}},
      {"scale_factor", {"pitch_ppm", "yaw_ppm"}},
      {"boresight_roll", {"roll_arcsec"}},
      {"axis_nonorthogonality", {"skew_arcsec"}},
      {"backlash", {"width_arcsec"}},
      {"settling", {"amplitude_arcsec", "tau_s"}},
      {"time_skew", {"skew_s"}},
      {"coefficients", {}},
      {"temperature", {"pitch_arcsec_per_c", "yaw_arcsec_per_c"}},
  };
  return k;
}

}  // namespace fpss
