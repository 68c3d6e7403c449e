// fpss-stand simulate: an in-process bench null-to-offset recording against a known truth.
#include <cstdio>

#include "base/text_file.h"
#include "calib/samples.h"
#include "fixtures/recording.h"
#include "procedures/procedure.h"
#include "stand/investigate/followup_design.h"
#include "stand/investigate/plan_session.h"
#include "stand/cli/commands.h"
#include "stand/cli/emulated_bench.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"
#include "stand/cli/file_options.h"

namespace fpss::cli {

void add_simulate(CLI::App& app, Runner& run) {
  struct Opts {
    std::string truth, bench, out, procedure;
    std::vector<std::string> effects;
    uint64_t seed = 1;
    GridPlan grid;
    FileOptions files;
  };
  auto o = std::make_shared<Opts>();
  auto* sub = app.add_subcommand("simulate", "Simulate a bench null-to-offset recording (samples CSV) with a known truth");
  expect_file(sub,
              o->files.input(sub, "--truth", o->truth,
                             "coefficient file of the sensor's true transfer function (default: published a-6-fpss1)"),
              o->truth, FileKind::coefficients);
  expect_file(sub, o->files.input(sub, "--bench", o->bench, "bench file (YAML)"), o->bench, FileKind::bench);
  o->files.output(sub, "--out", o->out, "samples CSV to write")->required();
  expect_file(sub,
              o->files.input(sub, "--procedure", o->procedure,
                             "run this procedure on the simulated bench instead of the grid (its moves, dwells and "
                             "slews; time_since_move_s recorded)"),
              o->procedure, FileKind::procedure);
  sub->add_option("--seed", o->seed, "random seed")->capture_default_str()->check(seed_check());
  sub->add_option("--effect", o->effects, "injected effect NAME:key=value,... (repeatable)")->check(effect_check());
  sub->add_option("--extent-deg", o->grid.extent_deg, "largest offset, deg")->capture_default_str()->check(CLI::Range(0.0, 0.5));
  sub->add_option("--step-deg", o->grid.step_deg, "offset step, deg")->capture_default_str()->check(CLI::PositiveNumber);
  sub->add_option("--samples-per-dwell", o->grid.samples_per_dwell, "samples per dwell")->capture_default_str()->check(CLI::Range(1, 100000));
  examples(sub, {"fpss-stand simulate --out rec.csv --truth calib/data/published/a-2-fpss1.json --seed 7",
                 "fpss-stand simulate --out rec.csv --procedure procedures/sim_to_real.yaml --bench "
                 "procedures/paper_mount_bench.yaml --seed 3"});
  sub->callback([o, &run] {
    run = [o] {
      o->files.check();
      BenchConfig cfg = o->bench.empty() ? default_bench_config() : load_bench_file(o->bench);
      if (!o->truth.empty()) cfg.truth = load_coefficients(o->truth);
      cfg.seed = o->seed;
      for (const auto& e : o->effects) cfg.effects.push_back(parse_effect(e));
      if (!o->procedure.empty()) {
        const Procedure proc = load_procedure(o->procedure);
        const SampleTable t = simulate_procedure(proc, emulated_settings(cfg), cfg);
        write_samples_csv(o->out, t);
        std::printf("wrote %zu samples (%s) to %s\n", t.size(), o->procedure.c_str(), o->out.c_str());
        return 0;
      }
      const SampleTable t = simulate_null_offset(cfg, o->grid);
      write_samples_csv(o->out, t);
      std::printf("wrote %zu samples (%zu offsets per axis) to %s\n", t.size(), o->grid.offsets_deg().size(),
                  o->out.c_str());
      return 0;
    };
  });
}

}  // namespace fpss::cli
