#include "procedures/design_procedure.h"

#include <fmt/format.h>

#include <vector>

#include <nlohmann/json.hpp>

namespace fpss {
namespace {

std::string deg_list(const std::vector<double>& v) {
  std::string out = "[";
  for (size_t i = 0; i < v.size(); ++i) out += fmt::format("{}{:.4f}", i ? ", " : "", v[i]);
  return out + "]";
}

// One line of text for a comment: no line breaks from a file's unit name.
std::string one_line(std::string s) {
  for (char& c : s) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return s;
}

}  // namespace

std::string design_procedure_text(const ExperimentDesign& d, const DesignInputs& in, const std::string& name) {
  std::vector<double> pitch_deg, yaw_deg;
  for (const auto& o : d.offsets) (o.pitch ? pitch_deg : yaw_deg).push_back(o.angle_deg);
  std::string t = fmt::format(
      "# Written by fpss-stand design: a null-to-offset calibration chosen to reach a largest 1-sigma of\n"
      "# the fitted angle of {} arcsec over +-{} deg in the least bench time (docs/calibration.md,\n"
      "# Experiment design). Predicted: {:.1f} s of bench time, largest 1-sigma {:.4f} arcsec (pitch),\n"
      "# {:.4f} arcsec (yaw){}.\n"
      "# Inputs: rate {} deg/s, acceleration {} deg/s^2, settle {} s, {} frames/s, count noise {} counts,\n"
      "# reference noise {} arcsec per frame, prior transfer function '{}'.\n",
      in.target_sigma_arcsec, in.extent_deg, d.bench_time_s, d.max_sigma_arcsec_pitch, d.max_sigma_arcsec_yaw,
      d.reached ? "" : "; TARGET NOT REACHED: " + one_line(d.note), in.rate_deg_s, in.accel_deg_s2, in.settle_s,
      in.frame_rate_hz, in.count_noise_counts, in.ref_noise_arcsec, one_line(in.prior.unit));
  t += fmt::format("name: {}\n", nlohmann::json(name).dump());  // a JSON string is a YAML string
  t += fmt::format(
      "description: >-\n  Designed null-to-offset calibration: {} offsets, {} frames per dwell, target 1-sigma {} "
      "arcsec.\n",
      d.offsets.size(), d.samples_per_dwell, in.target_sigma_arcsec);
  t += "steps:\n  - home\n  - null_offset_grid:\n";
  if (!pitch_deg.empty()) t += "      pitch_offsets_deg: " + deg_list(pitch_deg) + "\n";
  if (!yaw_deg.empty()) t += "      yaw_offsets_deg: " + deg_list(yaw_deg) + "\n";
  t += fmt::format("      settle_s: {}\n      frames: {}\n      max_invalid_frames: 0\n", in.settle_s,
                   d.samples_per_dwell);
  t += "  - calibrate:\n      method: differences\n";
  t += "  # Table 1 of the paper: mean residuals 0.26-0.79 arcsec, max 0.9-2.1 arcsec.\n";
  t += "  - check:\n      mean_abs_arcsec: 0.8\n      max_abs_arcsec: 2.1\n";
  return t;
}

}  // namespace fpss
