// fpss-stand diagnose (sim-to-real gap: which unmodelled effect, where, how far it shrinks) and
// fpss-stand blindtest (the diagnosis against random effects on the simulated bench).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <variant>
#include <unistd.h>

#include "base/errors.h"
#include "base/text_file.h"
#include "calib/coefficients.h"
#include "calib/diagnosis/diagnosis.h"
#include "calib/samples.h"
#include "procedures/procedure.h"
#include "procedures/yaml_diag.h"
#include "stand/blindtest/blindtest.h"
#include "stand/blindtest/joint_blindtest.h"
#include "stand/investigate/confusable.h"
#include "stand/investigate/followup_design.h"
#include "stand/cli/commands.h"
#include "stand/cli/emulated_bench.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/file_options.h"
#include "stand/cli/help.h"
#include "stand/cli/terminal.h"
#include "stand/catalogue/run_file.h"
#include "stand/session/diagnose_step.h"
#include "stand/report/diagnosis_page.h"

namespace fpss::cli {

namespace {

namespace fs = std::filesystem;

struct DiagnoseOpts {
  std::vector<std::string> models;       // FILE, or SERIAL=FILE with --run
  std::vector<std::string> model_files;  // the files they name (checked against the outputs)
  std::string model;                     // --data: the one model file (for the hints)
  std::string data, run_dir, out, report, emit_bench;
  std::vector<std::string> datas;  // every --data (several: a joint diagnosis)
  DiagnosisOptions d;
  bool partial = false;
  FileOptions files;
};

// What became of the run, in a line: a diagnosis of a run that stopped early says so.
std::string run_outcome_text(const RunFile& run) {
  std::string s = run.outcome;
  if (run.outcome != "completed" && run.stop_cause) s += fmt::format(" ({})", to_string(*run.stop_cause));
  if (run.reason && !run.reason->empty()) s += ": " + *run.reason;
  if (run.acceptance) {
    s += ", acceptance " + run.acceptance->verdict;
    if (run.acceptance->failed && !run.acceptance->failed->empty()) {
      s += fmt::format(" ({})", fmt::join(*run.acceptance->failed, ", "));
    }
  }
  return s + fmt::format("; {} of {} points recorded", run.points.completed, run.points.total);
}

// GAP.json's `run`: the run the recording is of and how it ended.
nlohmann::ordered_json run_json(const fs::path& run_dir, const RunFile& run) {
  nlohmann::ordered_json j{{"dir", run_dir.string()}, {"id", run.id_or(run_dir)}, {"outcome", run.outcome}};
  j["stop_cause"] = run.stop_cause ? nlohmann::ordered_json(to_string(*run.stop_cause)) : nlohmann::ordered_json();
  j["reason"] = run.reason ? nlohmann::ordered_json(*run.reason) : nlohmann::ordered_json();
  j["acceptance"] = run.acceptance ? nlohmann::ordered_json(run.acceptance->verdict) : nlohmann::ordered_json();
  j["points"] = {{"total", run.points.total}, {"completed", run.points.completed}};
  return j;
}

// The model a run was made against: its procedure's diagnose step's (resolved as the run resolved
// it, beside the procedure file run.json names); "" when it names none that is still there.
std::string model_of_run(const RunFile& run) {
  Diagnostics diag(run.procedure.file.value_or(run.procedure.name));
  const Procedure p = parse_procedure(run.procedure.text, run.procedure.file.value_or(run.procedure.name), diag);
  for (const Step& step : p.steps) {
    const auto* d = std::get_if<DiagnoseStep>(&step.body);
    if (d && step.valid && !d->model.empty() && fs::is_regular_file(d->model)) return d->model.string();
  }
  return "";
}

int diagnose_recordings(const DiagnoseOpts& o, const std::string& model_path,
                        const std::optional<nlohmann::ordered_json>& run);

// diagnose --run of a run of one unit: its recording (whatever the run's outcome) against --model,
// else the model its procedure's diagnose step names.
int diagnose_single_run(const fs::path& run_dir, const RunFile& run, DiagnoseOpts o) {
  std::string model;
  if (o.models.size() > 1) throw InputError(fmt::format("--run {}: a run of one unit takes one --model", run_dir.string()));
  if (!o.models.empty()) {
    model = o.models.front();
    const auto eq = model.find('=');
    if (eq != std::string::npos) {
      if (model.substr(0, eq) != run.unit) {
        throw InputError(fmt::format("--model {}: the run's unit is {}", model, run.unit));
      }
      model = model.substr(eq + 1);
    }
  } else {
    model = model_of_run(run);
    if (model.empty()) {
      throw InputError(fmt::format("--run {}: give --model (the run's procedure names no model file that is still there)",
                                   run_dir.string()));
    }
  }
  const fs::path samples = run_dir / run.files.samples.value_or("samples.csv");
  if (!fs::is_regular_file(samples)) {
    throw InputError(fmt::format("--run {}: the run has no recording ({} is missing)", run_dir.string(), samples.string()));
  }
  std::printf("run %s: %s\n", run.id_or(run_dir).c_str(), run_outcome_text(run).c_str());
  o.datas = {samples.string()};
  o.data = samples.string();
  return diagnose_recordings(o, model, run_json(run_dir, run));
}

// diagnose --run: a run of one unit (diagnose_single_run), or each unit's recording of several
// against its model (units/SERIAL/GAP.json and GAP.html), then what is the stand's and what each
// unit's (`out`). Exit 2 for a unit the run does not have.
int diagnose_run(const DiagnoseOpts& o) {
  const fs::path run_dir = o.run_dir;
  if (!fs::is_directory(run_dir)) throw InputError(fmt::format("--run {}: not a run folder", run_dir.string()));
  const RunFile run = read_run_file(run_dir);
  if (!run.units) return diagnose_single_run(run_dir, run, o);
  const std::vector<std::string>& models = o.models;
  const std::string& out = o.out;
  const DiagnosisOptions& opts = o.d;
  if (models.empty()) throw InputError(fmt::format("--run {}: a run of several units: give --model SERIAL=FILE for each", run_dir.string()));
  std::printf("run %s: %s\n", run.id_or(run_dir).c_str(), run_outcome_text(run).c_str());
  std::vector<std::pair<std::string, Diagnosis>> diagnosed;
  bool incomplete = false;
  for (const std::string& m : models) {
    const auto eq = m.find('=');
    if (eq == std::string::npos || eq == 0) {
      throw InputError(fmt::format("--model {}: with --run, give SERIAL=FILE (one per unit)", m));
    }
    const std::string serial = m.substr(0, eq), file = m.substr(eq + 1);
    const auto unit = std::find_if(run.units->begin(), run.units->end(), [&](const RunFileUnit& u) { return u.serial == serial; });
    if (unit == run.units->end()) {
      std::vector<std::string> serials;
      for (const auto& u : *run.units) serials.push_back(u.serial);
      throw InputError(fmt::format("--model {}: the run has no unit {} (it has {})", m, serial, fmt::join(serials, ", ")));
    }
    if (!unit->samples) throw InputError(fmt::format("--model {}: run.json names no samples of unit {}", m, serial));
    const CoefficientSet model = load_coefficients(file);
    DiagnosisFigures figures;
    Diagnosis d = diagnose(read_diagnosis_columns(run_dir / *unit->samples), model, opts, &figures);
    const fs::path dir = (run_dir / *unit->samples).parent_path();
    nlohmann::ordered_json j = d.to_json();
    j["model"] = file;
    write_gap_file(dir / "GAP.json", j);
    write_diagnosis_page((dir / "GAP.html").string(), d, figures);
    std::printf("unit %s: verdict %s, cause %s", serial.c_str(), d.verdict.c_str(), d.cause.c_str());
    for (size_t k = 1; k < d.causes.size(); ++k) std::printf(", then %s", d.causes[k].name.c_str());
    std::printf(" -> %s\n", (dir / "GAP.json").c_str());
    incomplete = incomplete || d.incomplete_recording();
    diagnosed.emplace_back(serial, std::move(d));
  }
  nlohmann::ordered_json j = joint_diagnosis_json(diagnosed, run.id_or(run_dir));
  j["run"] = run_json(run_dir, run);
  write_gap_file(out, j);  // the same content a run's diagnose step writes, and how the run ended
  for (const auto& s : j["stand_effects"]) {
    std::printf("stand: %s %s\n", s["name"].get<std::string>().c_str(), s["params"].dump().c_str());
  }
  for (const auto& [serial, effects] : j["unit_effects"].items()) {
    for (const auto& u : effects) {
      std::printf("unit %s: %s %s\n", serial.c_str(), u["name"].get<std::string>().c_str(), u["params"].dump().c_str());
    }
  }
  if (incomplete) {
    (o.partial ? print_note : print_error)("diagnose: this recording cannot tell every effect apart (each unit's "
                                           "GAP.json, not_observable; --partial accepts it)");
    return o.partial ? 0 : 2;
  }
  return 0;
}

// The recordings in o.datas diagnosed jointly against one model: GAP.json (with the run's outcome
// when they are a run's), the report, the emitted bench, and the verdict on the console.
int diagnose_recordings(const DiagnoseOpts& o, const std::string& model_path,
                        const std::optional<nlohmann::ordered_json>& run) {
  const CoefficientSet model = load_coefficients(model_path);
  // Straight into the columns the diagnosis reads (no whole table of every column in memory).
  std::vector<DiagnosisColumns> recordings;
  for (const std::string& path : o.datas) recordings.push_back(read_diagnosis_columns(path));
  DiagnosisFigures figures;
  Diagnosis d = diagnose(std::move(recordings), model, o.d, o.report.empty() ? nullptr : &figures);
  predict_best_followups(d, model);
  nlohmann::ordered_json j = d.to_json();
  j["model"] = model_path;
  if (run) j["run"] = *run;
  write_gap_file(o.out, j);
  if (!o.emit_bench.empty()) write_emitted_bench(o.emit_bench, d, model_path);
  if (!o.report.empty()) write_diagnosis_page(o.report, d, figures);
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
    (o.partial ? print_note : print_error)(
        fmt::format("diagnose: {}: this recording cannot tell every effect apart:", o.data));
    for (const auto& n : d.not_observable) {
      if (n.incomplete_recording) std::fprintf(stderr, "  %s: %s\n", n.name.c_str(), n.reason.c_str());
    }
    std::fprintf(stderr, "  (%s lists them under not_observable; --partial accepts such a recording)\n", o.out.c_str());
    return o.partial ? 0 : 2;
  }
  return 0;
}

void add_diagnose_command(CLI::App& app, Runner& run) {
  auto o = std::make_shared<DiagnoseOpts>();
  auto* sub = app.add_subcommand("diagnose", "Which unmodelled effect explains model(counts) - reference, checked on held-out steps");
  FileOptions& f = o->files;
  auto* model_opt = sub->add_option("--model", o->models,
                                    "the sim model: a coefficient file (JSON); with --run of several units, SERIAL=FILE for "
                                    "each unit (repeatable); with --run of one unit, default: the model its procedure's "
                                    "diagnose step names")
                        ->allow_extra_args(false);
  f.inputs("--model", o->model_files);
  expect_file(sub, model_opt, o->model, FileKind::coefficients);
  auto* data = sub->add_option("--data", o->datas,
                               "the real recording: a samples CSV (all phases; temperature_c used when present); "
                               "repeated: several recordings of one unit diagnosed jointly (one effect, one set of "
                               "parameters for all)")
                   ->allow_extra_args(false);
  f.inputs("--data", o->datas);
  expect_file(sub, data, o->data, FileKind::samples);
  auto* run_opt = sub->add_option("--run", o->run_dir,
                                  "a run folder, whatever the run's outcome (completed, a check or acceptance failed, "
                                  "aborted): its recording, the outcome printed and in GAP.json's run; of several "
                                  "units: each unit's diagnosis into units/SERIAL/GAP.json, and --out tells the "
                                  "stand's effects from each unit's");
  data->excludes(run_opt);
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
  sub->add_option("--materiality-arcsec", o->d.materiality_arcsec,
                  "what is material, for the candidates' status (default: the noise floor of one dwell mean)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--calibrated-range-arcsec", o->d.calibrated_range_arcsec,
                  "the calibrated half-range a refitted transfer function must be measured over (and a follow-up "
                  "plans within)")
      ->default_val(DiagnosisOptions{}.calibrated_range_arcsec)
      ->check(CLI::Range(kMinCalibratedRangeArcsec, kMaxCalibratedRangeArcsec));
  examples(sub, {"fpss-stand diagnose --model calib/data/published/a-6-fpss1.json --data RUN_DIR/samples.csv "
                 "--out gap.json --report gap.html --partial",
                 "fpss-stand diagnose --run RUN_DIR --model FPSS1-A6=calib/data/published/a-6-fpss1.json "
                 "--model FPSS2-A6=calib/data/published/a-6-fpss2.json --out joint.json --partial"});
  sub->callback([o, &run] {
    run = [o] {
      for (const std::string& m : o->models) {
        const auto eq = m.find('=');
        o->model_files.push_back(o->run_dir.empty() || eq == std::string::npos ? m : m.substr(eq + 1));
      }
      if (o->run_dir.empty() && !o->models.empty()) o->model = o->models.front();
      if (!o->datas.empty()) o->data = o->datas.front();
      o->files.check();
      if (!o->run_dir.empty()) return diagnose_run(*o);
      if (o->data.empty()) throw InputError("diagnose: give --data (one recording) or --run (a run folder)");
      if (o->models.size() != 1 || o->models.front().empty()) {
        throw InputError("diagnose --data: give one --model (a coefficient file); SERIAL=FILE pairs go with --run");
      }
      return diagnose_recordings(*o, o->models.front(), std::nullopt);
    };
  });
}

void add_blindtest_command(CLI::App& app, Runner& run) {
  struct Opts {
    BlindTestOptions b;
    bool json = false, quiet = false, units = false, investigate = false;
  };
  auto o = std::make_shared<Opts>();
  auto* sub = app.add_subcommand("blindtest", "Blind check of the diagnosis: random effects on the simulated bench");
  sub->add_option("--cases", o->b.cases, "number of cases (classes drawn in shuffled blocks of all eleven)")->default_val(22);
  sub->add_option("--seed", o->b.seed, "seed of the draws and of the bench noise")->default_val(1)->check(seed_check());
  sub->add_flag("--json", o->json, "print the results as JSON");
  sub->add_option("--save", o->b.save_dir,
                  "folder for every case's recording, model, truth and GAP.json (to re-run `diagnose` on them)");
  sub->add_flag("--quiet", o->quiet, "no progress lines on stderr");
  sub->add_flag("--pairs", o->b.pairs, "two different effects per case (correct when both are reported)");
  sub->add_flag("--units", o->units,
                "two units on one gimbal pass, a stand effect for both and a unit effect on one: is each attributed "
                "to the stand or to its unit (diagnose --run)");
  sub->add_flag("--investigate", o->investigate,
                "the confusable and unseen cases, each investigated to the end with follow-ups (--cases per kind; "
                "--save keeps every run, follow-up and INVESTIGATION's GAP.json)");
  examples(sub, {"fpss-stand blindtest --cases 2 --seed 3", "fpss-stand blindtest --cases 22 --pairs --json"});
  sub->callback([o, &run] {
    run = [o] {
      if (o->b.cases < 1) throw InputError("--cases must be at least 1");
      if (o->investigate) {
        const std::filesystem::path work =
            o->b.save_dir.empty() ? std::filesystem::temp_directory_path() / fmt::format("fpss-confusable-{}", ::getpid())
                                  : std::filesystem::path(o->b.save_dir);
        const ConfusableReport rep = run_confusable_cases(o->b.cases, o->b.seed, work, [&](const ConfusableCase& c) {
          if (!o->quiet) {
            std::fprintf(stderr, "%-24s %-22s %s follow-ups %d (%.2fx) %s\n", c.kind.c_str(), c.truth.c_str(),
                         c.success() ? "ok  " : "MISS", c.followups, c.followup_ratio, c.stop_reason.c_str());
          }
        });
        if (o->b.save_dir.empty()) std::filesystem::remove_all(work);
        if (o->json) std::printf("%s\n", rep.summary().dump(1).c_str());
        else std::printf("%s", rep.to_text().c_str());
        return 0;
      }
      if (o->units) {
        const JointBlindReport rep = run_joint_blindtest(o->b.cases, o->b.seed, [&](const JointBlindCase& c) {
          if (!o->quiet) {
            std::fprintf(stderr, "case %3d  stand %-22s + %-15s on %s  %s\n", c.index, c.stand_effect.c_str(),
                         c.unit_effect.c_str(), c.unit_serial.c_str(), c.correct ? "ok" : "MISS");
          }
        });
        if (o->json) std::printf("%s\n", rep.to_json().dump(1).c_str());
        else std::printf("%s", rep.to_text().c_str());
        return 0;
      }
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
