// fpss-stand design: the cheapest null-to-offset calibration that reaches a target 1-sigma
// (calib/design.h), from the stand's or the emulated bench's rates, settle, frame rate and noise.
#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "base/errors.h"
#include "base/text_file.h"
#include "calib/coefficients.h"
#include "calib/design.h"
#include "fixtures/bench.h"
#include "procedures/design_procedure.h"
#include "stand/cli/commands.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"
#include "stand/config/stand_config.h"

namespace fpss::cli {
namespace {

struct DesignArgs {
  double target_sigma_arcsec = 0;
  std::string stand_file, bench_file, prior_file, out;
  bool emulate = false, json = false, prior_only = false;
  double extent_deg = DesignInputs{}.extent_deg, settle_s = DesignInputs{}.settle_s;
  std::optional<double> count_noise_counts, ref_noise_arcsec;
};

// The bench's rates, frame rate and noise: from the stand file, or from the emulated bench.
DesignInputs bench_inputs(const DesignArgs& a, DesignSources& src) {
  DesignInputs in;
  if (!a.stand_file.empty()) {
    const StandConfig stand = load_stand_file(a.stand_file);
    in.rate_deg_s = stand.bench.profile_rate_arcsec_s / 3600;
    in.accel_deg_s2 = stand.bench.acceleration_arcsec_s2 / 3600;
    in.frame_rate_hz = stand.bench.sample_rate_hz;
    in.prior = load_published("a-6-fpss1");
    src = {"stand file " + a.stand_file, "assumed (0.3 counts)", "published set a-6-fpss1"};
    return in;
  }
  const BenchConfig b = a.bench_file.empty() ? default_bench_config() : load_bench_file(a.bench_file);
  in.rate_deg_s = b.max_rate_arcsec_s / 3600;
  in.accel_deg_s2 = b.accel_arcsec_s2 / 3600;
  in.frame_rate_hz = b.sample_rate_hz;
  in.count_noise_counts = b.count_noise;
  in.ref_noise_arcsec = b.encoder_noise_arcsec;
  in.prior = b.truth;
  src = {a.bench_file.empty() ? "emulated bench (default)" : "emulated bench " + a.bench_file, "the emulated bench",
         "the emulated bench's truth"};
  return in;
}

DesignInputs design_inputs(const DesignArgs& a, DesignSources& src) {
  DesignInputs in = bench_inputs(a, src);
  in.target_sigma_arcsec = a.target_sigma_arcsec;
  in.extent_deg = a.extent_deg;
  in.settle_s = a.settle_s;
  if (!a.prior_file.empty()) {
    in.prior = load_coefficients(a.prior_file);
    src.prior = a.prior_file;
  }
  if (a.count_noise_counts) {
    in.count_noise_counts = *a.count_noise_counts;
    src.count_noise = "command line";
  } else if (auto n = in.prior.extra.find("count_noise_counts"); n != in.prior.extra.end() && n->is_number()) {
    in.count_noise_counts = n->get<double>();
    src.count_noise = "prior coefficient file";
  }
  if (a.ref_noise_arcsec) in.ref_noise_arcsec = *a.ref_noise_arcsec;
  // Robust unless told otherwise: the unit may have any of the published transfer functions.
  if (!a.prior_only) {
    for (const auto& name : published_names()) {
      CoefficientSet set = load_published(name);
      if (is_suspect(set)) continue;
      set.unit = name;
      in.also_for.push_back(std::move(set));
    }
  }
  return in;
}

void print_design(const nlohmann::ordered_json& j, const std::string& out) {
  const auto& g = j["paper_grid"];
  std::printf("design: %s\n", j["reached"].get<bool>() ? "target reached" : "TARGET NOT REACHED");
  if (j.contains("note")) std::printf("  %s\n", j["note"].get<std::string>().c_str());
  std::printf("  %d offsets, %d frames per dwell\n", j["offsets"].get<int>(), j["samples_per_dwell"].get<int>());
  std::printf("  predicted bench time %.1f s, largest 1-sigma %.4f arcsec (pitch), %.4f arcsec (yaw)\n",
              j["bench_time_s"].get<double>(), j["max_sigma_arcsec_pitch"].get<double>(),
              j["max_sigma_arcsec_yaw"].get<double>());
  std::printf("  the paper's grid on this bench: %.1f s, %.4f / %.4f arcsec\n", g["bench_time_s"].get<double>(),
              g["max_sigma_arcsec_pitch"].get<double>(), g["max_sigma_arcsec_yaw"].get<double>());
  std::printf("  noise %.3g counts (%s); prior %s\n", j["inputs"]["count_noise_counts"].get<double>(),
              j["inputs"]["count_noise_source"].get<std::string>().c_str(),
              j["inputs"]["prior"].get<std::string>().c_str());
  if (const size_t n = j["inputs"]["robust_over"].size(); n > 0) {
    std::printf("  robust: the sigmas hold under the prior and %zu published transfer functions (largest under %s, "
                "%s; --prior-only: for the prior alone)\n",
                n, j["limited_by_pitch"].get<std::string>().c_str(), j["limited_by_yaw"].get<std::string>().c_str());
  }
  if (!out.empty()) std::printf("  procedure: %s\n", out.c_str());
}

int run_design(const DesignArgs& a) {
  if (!(std::isfinite(a.target_sigma_arcsec) && a.target_sigma_arcsec > 0)) {
    throw InputError(fmt::format("design: --target-sigma-arcsec {}: expected a number > 0", a.target_sigma_arcsec));
  }
  if (!a.bench_file.empty() && !a.emulate) throw InputError("design: --bench needs --emulate");
  if (!a.out.empty()) check_output_path(a.out);
  DesignSources src;
  const DesignInputs in = design_inputs(a, src);
  ExperimentDesign d;
  try {
    d = design_experiment(in);
  } catch (const std::invalid_argument& e) {
    throw InputError(fmt::format("design: {}", e.what()));
  }
  const auto j = design_report_json(d, in, src);
  if (d.reached && !a.out.empty()) {
    write_text_atomic(a.out, design_procedure_text(d, in, std::filesystem::path(a.out).stem().string()));
  }
  if (a.json) std::printf("%s\n", j.dump(2).c_str());
  else print_design(j, d.reached ? a.out : "");
  return d.reached ? 0 : 1;
}

}  // namespace

void add_design(CLI::App& app, Runner& run) {
  auto a = std::make_shared<DesignArgs>();
  auto* sub = app.add_subcommand(
      "design", "Choose the null-to-offset calibration that reaches a target 1-sigma in the least bench time");
  sub->add_option("--target-sigma-arcsec", a->target_sigma_arcsec,
                  "largest 1-sigma of the fitted angle over the range, both axes (arcsec)")
      ->required();
  auto* stand = sub->add_option("--stand", a->stand_file, "stand file: the gimbal's rate and acceleration, frame rate");
  auto* emulate = sub->add_flag("--emulate", a->emulate, "the emulated bench's rates, frame rate, noise and truth");
  stand->excludes(emulate);
  expect_file(sub, stand, a->stand_file, FileKind::stand);
  expect_file(sub, sub->add_option("--bench", a->bench_file, "with --emulate: the emulator's bench file"), a->bench_file,
              FileKind::bench);
  expect_file(sub,
              sub->add_option("--prior", a->prior_file,
                              "coefficient file near the unit's (default: the bench's truth, or "
                              "the published set a-6-fpss1 with --stand)"),
              a->prior_file, FileKind::coefficients);
  sub->add_flag("--prior-only", a->prior_only,
                "design for the prior alone (a unit whose transfer function is well known); by default the sigmas "
                "hold under every published transfer function too");
  sub->add_option("--count-noise-counts", a->count_noise_counts, "count noise per frame before rounding");
  sub->add_option("--ref-noise-arcsec", a->ref_noise_arcsec, "reference noise per frame (arcsec)");
  sub->add_option("--extent-deg", a->extent_deg, fmt::format("offsets within +-this along each axis (default {})", DesignInputs{}.extent_deg));
  sub->add_option("--settle-s", a->settle_s, fmt::format("settle after each move (default {} s)", DesignInputs{}.settle_s));
  sub->add_option("--out", a->out, "write the procedure file here (when the target is reached)");
  sub->add_flag("--json", a->json, "print the design as JSON");
  examples(sub, {"fpss-stand design --target-sigma-arcsec 0.5 --emulate --out designed.yaml",
                 "fpss-stand design --target-sigma-arcsec 1 --stand procedures/example_stand.yaml --prior-only --json"});
  sub->callback([a, &run] { run = [a] { return run_design(*a); }; });
}

}  // namespace fpss::cli
