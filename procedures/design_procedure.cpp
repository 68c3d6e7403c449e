#include "procedures/design_procedure.h"

#include <fmt/format.h>

#include <vector>

#include <nlohmann/json.hpp>

#include "procedures/procedure.h"

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

namespace fpss {
namespace {

// The paper's grid as shipped (procedures/discrete_grid.yaml, read and expanded by the procedure
// language) on the same bench, for comparison.
nlohmann::ordered_json paper_grid(const DesignInputs& in) {
  const Procedure grid = load_procedure(shipped_procedures_dir() / "discrete_grid.yaml");
  std::vector<DesignOffset> offs;
  int frames = 0;
  for (const auto& step : grid.steps) {
    const auto* g = std::get_if<GridStep>(&step.body);
    if (!g) continue;
    frames = g->frames.count(in.frame_rate_hz);
    for (StandAxis axis : g->axes) {
      for (double o : g->offsets_arcsec(axis)) offs.push_back({axis == StandAxis::pitch, o / 3600});
    }
  }
  nlohmann::ordered_json j;
  j["bench_time_s"] = design_time_s(in, offs, frames);
  j["max_sigma_arcsec_pitch"] = predicted_max_sigma_arcsec(in, offs, frames, true);
  j["max_sigma_arcsec_yaw"] = predicted_max_sigma_arcsec(in, offs, frames, false);
  return j;
}

}  // namespace

nlohmann::ordered_json design_report_json(const ExperimentDesign& d, const DesignInputs& in,
                                          const DesignSources& src) {
  nlohmann::ordered_json inputs = {
      {"bench", src.bench},          {"rate_deg_s", in.rate_deg_s},
      {"accel_deg_s2", in.accel_deg_s2}, {"settle_s", in.settle_s},
      {"frame_rate_hz", in.frame_rate_hz}, {"count_noise_counts", in.count_noise_counts},
      {"count_noise_source", src.count_noise}, {"ref_noise_arcsec", in.ref_noise_arcsec},
      {"prior", src.prior},          {"extent_deg", in.extent_deg}};
  nlohmann::ordered_json robust = nlohmann::ordered_json::array();
  for (const auto& set : in.also_for) robust.push_back(set.unit);
  inputs["robust_over"] = robust;
  nlohmann::ordered_json offsets = nlohmann::ordered_json::array();
  for (const auto& o : d.offsets) offsets.push_back({{"axis", o.pitch ? "pitch" : "yaw"}, {"angle_deg", o.angle_deg}});
  nlohmann::ordered_json j = {{"reached", d.reached}, {"target_sigma_arcsec", in.target_sigma_arcsec},
                              {"bench_time_s", d.bench_time_s}, {"max_sigma_arcsec_pitch", d.max_sigma_arcsec_pitch},
                              {"max_sigma_arcsec_yaw", d.max_sigma_arcsec_yaw},
                              {"limited_by_pitch", d.limited_by_pitch}, {"limited_by_yaw", d.limited_by_yaw},
                              {"samples_per_dwell", d.samples_per_dwell}, {"offsets", d.offsets.size()},
                              {"offsets_deg", offsets}, {"inputs", inputs}, {"paper_grid", paper_grid(in)}};
  if (!d.note.empty()) j["note"] = d.note;
  return j;
}

}  // namespace fpss
