// fpss-stand diagnose (sim-to-real gap: which unmodelled effect, where, how far it shrinks) and
// fpss-stand blindtest (the diagnosis against random effects on the simulated bench).
#include <cstdio>

#include "base/errors.h"
#include "base/text_file.h"
#include "calib/coefficients.h"
#include "calib/diagnosis/diagnosis.h"
#include "calib/samples.h"
#include "stand/blindtest/blindtest.h"
#include "stand/cli/commands.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/file_options.h"
#include "stand/cli/help.h"
#include "stand/report/diagnosis_page.h"

namespace fpss::cli {

namespace {

void write_json_file(const std::string& path, const nlohmann::ordered_json& j) {
  write_text_atomic(path, j.dump(1) + '\n');
}

void add_diagnose_command(CLI::App& app, Runner& run) {
  struct Opts {
    std::string model, data, out, report, emit_bench;
    DiagnosisOptions d;
    bool partial = false;
    FileOptions files;
  };
  auto o = std::make_shared<Opts>();
  auto* sub = app.add_subcommand("diagnose", "Which unmodelled effect explains model(counts) - reference, checked on held-out steps");
  FileOptions& f = o->files;
  expect_file(sub, f.input(sub, "--model", o->model, "the sim model: a coefficient file (JSON)")->required(), o->model,
              FileKind::coefficients);
  expect_file(sub,
              f.input(sub, "--data", o->data,
                      "the real recording: a samples CSV (all phases; temperature_c used when present)")
                  ->required(),
              o->data, FileKind::samples);
  f.output(sub, "--out", o->out, "GAP.json to write")->required();
  f.output(sub, "--report", o->report, "GAP.html: residuals against every factor before/after, residual map");
  f.output(sub, "--emit-bench", o->emit_bench,
           "write an emulator bench file: the model as truth, the diagnosed causes as effects (a refitted transfer "
           "function goes next to it, as NAME.coefficients.json)",
           emitted_coefficients_path);
  sub->add_option("--settle-s", o->d.settle_s,
                  "time from a dwell's arrival to its first sample, when no time_since_move_s column says it")
      ->default_val(0.0);
  sub->add_option("--max-skew-s", o->d.max_skew_s, "largest sampling-time shift searched (and slew-end margin)")->default_val(0.25);
  sub->add_flag("--partial", o->partial,
                "accept a recording that cannot reveal every effect (no slews or no offsets): exit 0 instead of 2");
  examples(sub, {"fpss-stand diagnose --model calib/data/published/a-6-fpss1.json --data RUN_DIR/samples.csv "
                 "--out gap.json --report gap.html --partial"});
  sub->callback([o, &run] {
    run = [o] {
      o->files.check();
      const CoefficientSet model = load_coefficients(o->model);
      // Straight into the columns the diagnosis reads (no whole table of every column in memory).
      DiagnosisFigures figures;
      Diagnosis d = diagnose(read_diagnosis_columns(o->data), model, o->d, o->report.empty() ? nullptr : &figures);
      nlohmann::ordered_json j = d.to_json();
      j["model"] = o->model;
      write_json_file(o->out, j);
      if (!o->emit_bench.empty()) write_emitted_bench(o->emit_bench, d, o->model);
      if (!o->report.empty()) write_diagnosis_page(o->report, d, figures);
      std::printf("verdict: %s\n%s\ncause: %s", d.verdict.c_str(), d.verdict_sentence.c_str(), d.cause.c_str());
      for (size_t k = 1; k < d.causes.size(); ++k) std::printf(", then %s", d.causes[k].name.c_str());
      std::printf("\ngap: %.4f arcsec before, %.4f after (noise floor %.4f), held-out rows %zu\n", d.gap_before_arcsec,
                  d.gap_after_all_arcsec, d.noise_floor_arcsec, j["split"]["heldout_rows"].get<size_t>());
      if (!d.causes.empty()) std::printf("params: %s\n", d.causes.front().params.dump().c_str());
      if (!d.where.empty()) {
        std::printf("where: %s (%s), %.0f %% of the gap\n", d.where.front().factor.c_str(), d.where.front().axis.c_str(),
                    100 * d.where.front().share);
      }
      if (d.incomplete_recording()) {
        std::fprintf(stderr, "fpss-stand diagnose: %s: this recording cannot tell every effect apart:\n", o->data.c_str());
        for (const auto& n : d.not_observable) {
          if (n.incomplete_recording) std::fprintf(stderr, "  %s: %s\n", n.name.c_str(), n.reason.c_str());
        }
        std::fprintf(stderr, "  (%s lists them under not_observable; --partial accepts such a recording)\n", o->out.c_str());
        return o->partial ? 0 : 2;
      }
      return 0;
    };
  });
}

void add_blindtest_command(CLI::App& app, Runner& run) {
  struct Opts {
    BlindTestOptions b;
    bool json = false, quiet = false;
  };
  auto o = std::make_shared<Opts>();
  auto* sub = app.add_subcommand("blindtest", "Blind check of the diagnosis: random effects on the simulated bench");
  sub->add_option("--cases", o->b.cases, "number of cases (classes drawn in shuffled blocks of all eleven)")->default_val(22);
  sub->add_option("--seed", o->b.seed, "seed of the draws and of the bench noise")->default_val(1);
  sub->add_flag("--json", o->json, "print the results as JSON");
  sub->add_option("--save", o->b.save_dir,
                  "folder for every case's recording, model, truth and GAP.json (to re-run `diagnose` on them)");
  sub->add_flag("--quiet", o->quiet, "no progress lines on stderr");
  sub->add_flag("--pairs", o->b.pairs, "two different effects per case (correct when both are reported)");
  examples(sub, {"fpss-stand blindtest --cases 2 --seed 3", "fpss-stand blindtest --cases 22 --pairs --json"});
  sub->callback([o, &run] {
    run = [o] {
      if (o->b.cases < 1) throw InputError("--cases must be at least 1");
      const BlindTestReport rep = run_blindtest(o->b, [&](const BlindCase& c) {
        if (o->quiet) return;
        std::string got = c.cause;
        for (size_t k = 1; k < c.causes.size(); ++k) got += "+" + c.causes[k];
        std::fprintf(stderr, "case %3d  %-22s -> %-22s %s  gap %.3f -> %.3f (noise %.3f)\n", c.index, c.truth.c_str(),
                     got.c_str(), c.correct ? "ok  " : "MISS", c.gap_before_arcsec, c.gap_after_all_arcsec,
                     c.noise_floor_arcsec);
      });
      if (o->json) std::printf("%s\n", rep.to_json().dump(1).c_str());
      else std::printf("%s", rep.to_text().c_str());
      return 0;
    };
  });
}

}  // namespace

void add_diagnose(CLI::App& app, Runner& run) {
  add_diagnose_command(app, run);
  add_blindtest_command(app, run);
}

}  // namespace fpss::cli
