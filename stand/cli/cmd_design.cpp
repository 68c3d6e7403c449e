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
#include "stand/cli/terminal.h"
#include "stand/config/stand_config.h"
#include "stand/investigate/followup_design.h"
#include "base/json_file.h"

namespace fpss::cli {
namespace {

struct DesignArgs {
  double target_sigma_arcsec = 0;
  std::string discriminate, observe, model;  // a follow-up from a GAP.json
  double max_bench_s = 0;
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

// The model the diagnosis used: --model, else the GAP.json's `model` as written or relative to it.
std::string followup_model_path(const std::string& given, const nlohmann::ordered_json& gap, const std::string& gap_path) {
  if (!given.empty()) return given;
  const std::string m = gap.value("model", std::string());
  if (m.empty()) throw InputError(fmt::format("{}: names no model: give --model FILE", gap_path));
  if (std::filesystem::exists(m)) return m;
  const auto beside = std::filesystem::path(gap_path).parent_path() / m;
  if (std::filesystem::exists(beside)) return beside.string();
  throw InputError(fmt::format("{}: its model {} is not found (give --model FILE)", gap_path, m));
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

// design --discriminate/--observe: the follow-up run from a GAP.json, on the stand's or the
// emulated bench's moves; exit 1 with no file when nothing within the budget separates or bounds.
int run_followup_design(const DesignArgs& a) {
  if (a.stand_file.empty() && !a.emulate) {
    throw InputError("design --discriminate/--observe: give --stand STAND.yaml or --emulate (the bench the follow-up runs on)");
  }
  if (!a.bench_file.empty() && !a.emulate) throw InputError("design: --bench needs --emulate");
  if (a.out.empty()) throw InputError("design --discriminate/--observe: give --out FOLLOWUP.yaml");
  check_output_path(a.out);
  if (!a.discriminate.empty() && !a.observe.empty() && a.discriminate != a.observe) {
    throw InputError("design: --discriminate and --observe name different files (give one GAP.json, or both the same)");
  }
  const std::string gap_path = a.discriminate.empty() ? a.observe : a.discriminate;
  FollowupRequest r;
  r.gap = nlohmann::ordered_json::parse(read_json_file(gap_path, "diagnosis (GAP.json)").dump());
  r.discriminate = !a.discriminate.empty();
  r.observe = !a.observe.empty();
  r.max_bench_s = a.max_bench_s;
  r.name = std::filesystem::path(a.out).stem().string();
  r.model = load_coefficients(followup_model_path(a.model, r.gap, gap_path));
  FollowupBench fb = followup_bench(a.stand_file, a.bench_file);
  r.settings = fb.settings;
  r.bench = std::move(fb.bench);
  if (a.emulate) r.start_s = 0;  // `run --emulate` starts a fresh emulated bench, its clock at zero
  const FollowupDesign d = design_followup(r);
  if (d.found || d.useful) write_text_atomic(a.out, d.procedure_text);
  if (a.json) {
    std::printf("%s\n", d.to_json().dump(2).c_str());
  } else {
    for (const auto& p : d.pairs) {
      std::printf("%s vs %s: expected log-likelihood ratio %.1f (separating from %.0f)%s\n", p.a.c_str(), p.b.c_str(),
                  p.expected_log_lr, kSeparatingLogLR, p.separated ? "" : " NOT SEPARATED");
    }
    for (const auto& b : d.bounds) {
      std::printf("%s: seen from %.4f arcsec where it acts (materiality %.4f)%s\n", b.name.c_str(), b.limit_arcsec,
                  d.materiality_arcsec, b.bounded ? "" : " NOT BOUNDED");
    }
    for (const auto& u : d.unreachable) std::printf("not planned: %s\n", u.c_str());
    std::printf("bench time: %.0f s of a budget of %.0f s (the recordings so far: %.0f s)\n", d.bench_s, d.budget_s,
                d.first_bench_s);
    if (d.found || d.useful) std::printf("moves: %s\nprocedure: %s\n", fmt::format("{}", fmt::join(d.moves, "; ")).c_str(), a.out.c_str());
  }
  if (!(d.found || d.useful)) {
    print_error(fmt::format("design: {}: nothing within {:.0f} s of bench time separates or bounds what was asked; "
                            "no file written", gap_path, d.budget_s));
    return 1;
  }
  return 0;
}

int run_design(const DesignArgs& a) {
  if (!a.discriminate.empty() || !a.observe.empty()) return run_followup_design(a);
  if (a.target_sigma_arcsec == 0) {
    throw InputError("design: give --target-sigma-arcsec (a calibration grid) or --discriminate/--observe GAP.json (a "
                     "follow-up)");
  }
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
  auto* target = sub->add_option("--target-sigma-arcsec", a->target_sigma_arcsec,
                                 "largest 1-sigma of the fitted angle over the range, both axes (arcsec)");
  auto* disc = sub->add_option("--discriminate", a->discriminate,
                               "GAP.json: design the follow-up run that separates its ambiguous candidates");
  auto* obs = sub->add_option("--observe", a->observe,
                              "GAP.json: design the follow-up run that bounds its unbounded candidates below the "
                              "materiality (with --discriminate, the same file: both at once)");
  target->excludes(disc)->excludes(obs);
  sub->add_option("--max-bench-s", a->max_bench_s,
                  "bench time the follow-up may take (default: half the recordings' bench time)")
      ->check(CLI::PositiveNumber);
  expect_file(sub, sub->add_option("--model", a->model, "with --discriminate/--observe: the sim model (default: the "
                                                        "GAP.json's model)"),
              a->model, FileKind::coefficients);
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
                 "fpss-stand design --discriminate GAP.json --observe GAP.json --emulate --out followup.yaml"});
  sub->callback([a, &run] { run = [a] { return run_design(*a); }; });
}

}  // namespace fpss::cli
