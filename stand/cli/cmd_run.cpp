// fpss-stand run: validate a procedure and a stand, then run it on the bench (real or an emulator child), or --resume a run.
#include <unistd.h>

#include <fmt/format.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "base/errors.h"
#include "base/text_file.h"
#include "procedures/plan.h"
#include "procedures/procedure.h"
#include "stand/catalogue/catalogue.h"
#include "stand/cli/catalogue_option.h"
#include "stand/cli/commands.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"
#include "stand/cli/emulated_bench.h"
#include "stand/cli/run_lookup.h"
#include "stand/cli/terminal.h"
#include "stand/config/stand_config.h"
#include "stand/investigate/followup_design.h"
#include "stand/session/session.h"

namespace fpss::cli {

namespace {

namespace fs = std::filesystem;

struct RunArgs : BenchChoiceArgs {
  std::string procedure, runs_dir = "runs", resume, catalogue;
  bool dry_run = false, progress = false, no_progress = false, quiet = false;
  std::string unit_serial, operator_name;
  double catalogue_wait_s = 120;
};

// --resume RUN: a run folder's path, or a run within --runs-dir (its id, a unique prefix, latest).
fs::path resume_folder(const RunArgs& a) {
  if (fs::is_regular_file(fs::path(a.resume) / "run.json") || a.resume.find('/') != std::string::npos) return a.resume;
  return find_run_in(a.resume, a.runs_dir).value_or(fs::path(a.resume));
}

int run_command(const RunArgs& a) {
  SessionRequest req;
  req.runs_dir = a.runs_dir;
  req.tty = draw_progress(a.progress, a.no_progress, a.quiet);
  req.quiet = a.quiet;
  if (::isatty(STDIN_FILENO)) req.keys_fd = STDIN_FILENO;  // p pause, r resume, a abort
  req.operator_name = a.operator_name;
  // A diagnose step's look-alikes get the run that would tell them apart, as `diagnose` gives them.
  req.predict_followups = [](Diagnosis& d, const CoefficientSet& model) { predict_best_followups(d, model); };

  if (!a.resume.empty()) {
    if (!a.procedure.empty() || !a.stand_file.empty() || a.emulate || a.dry_run) {
      throw InputError("run --resume RUN_DIR takes the procedure, stand and bench from RUN_DIR/run.json: give no "
                       "procedure, --stand, --emulate or --dry-run with it");
    }
    req.resume_dir = canonical_run_dir(resume_folder(a));
    const RunInfo info = read_run_info(req.resume_dir);
    Diagnostics dp(info.procedure_origin + " (as recorded in run.json)");
    req.procedure = parse_procedure(info.procedure_text, info.procedure_origin, dp);
    req.procedure.text = info.procedure_text;
    dp.throw_if_any();
    if (info.emulator) {
      req.emulator = *info.emulator;
      if (!info.stand_text.empty()) {
        Diagnostics ds(info.stand_origin);
        req.stand = parse_stand(info.stand_text, info.stand_origin, ds);
        ds.throw_if_any();
        adapt_to_emulator(req.stand, info.emulator->speed);
      } else {
        req.stand = emulated_stand(info.emulator->speed);
      }
    } else {
      Diagnostics ds(info.stand_origin);
      req.stand = parse_stand(info.stand_text, info.stand_origin, ds);
      ds.throw_if_any();
    }
  } else {
    if (a.procedure.empty()) throw InputError("run: give a procedure file (or --resume RUN_DIR)");
    if (a.stand_file.empty() && !a.emulate) {
      throw InputError("run: give --stand STAND.yaml for a real bench or --emulate for the emulated one");
    }
    if (!a.emulate) require_emulate_for_options(a.emu, "run");
    // Validate everything before anything moves, and report every error of both files at once.
    const std::string ptext = read_text_file(a.procedure, "procedure file", kMaxConfigFileBytes);
    Diagnostics dp(a.procedure);
    req.procedure = parse_procedure(ptext, a.procedure, dp);
    Diagnostics ds(a.stand_file);
    req.stand = stand_for_run(a.stand_file, a.emulate, a.emu.speed, ds);
    // A real bench's unit must report this serial (as accept --unit), checked before anything moves.
    if (!a.emulate && !a.unit_serial.empty()) req.stand.unit_serial = a.unit_serial;
    // The plan is checked against the stand even when some steps are broken (those are skipped),
    // but not against a broken stand file, whose limits would be guesses.
    if (ds.empty()) expand(req.procedure, req.stand.bench, dp);
    Diagnostics all(a.procedure);
    all.merge(ds);
    all.merge(dp);
    all.throw_if_any();
    if (a.dry_run) {
      Diagnostics unused(a.procedure);
      const Plan plan = expand(req.procedure, req.stand.bench, unused);
      std::fputs(format_plan(req.procedure, plan, req.stand.bench).c_str(), stdout);
      return 0;
    }
    if (a.emulate) req.emulator = emulator_spec(a.emu, a.unit_serial);
  }
  // "" keeps the session's default: RUNS_DIR/stand.db, or the run folder's parent on a resume.
  req.catalogue = chosen_catalogue(a.catalogue, req.stand.catalogue);
  req.catch_up_s = a.catalogue_wait_s;
  // A resumed run's bench is served by the binary running now, not the one recorded.
  if (req.emulator) req.emulator->exe = this_binary();

  const SessionResult r = run_session(req);
  const std::string dir = r.run_dir.string();
  if (r.outcome == RunOutcome::completed) {
    const std::string skipped =
        r.points_skipped ? fmt::format(" ({} skipped by the adaptive stop)", r.points_skipped) : std::string();
    std::printf("run completed: %lld/%lld points%s in %.1f s -> %s\n", static_cast<long long>(r.points_done),
                static_cast<long long>(r.points_total), skipped.c_str(), r.wall_s, dir.c_str());
  } else {
    if (a.quiet) print_error(fmt::format("run {}: {}", to_string(r.outcome), r.reason));
    std::printf("run %s: %lld/%lld points -> %s\n", to_string(r.outcome), static_cast<long long>(r.points_done),
                static_cast<long long>(r.points_total), dir.c_str());
    if (r.points_done < r.points_total) std::printf("resume with: fpss-stand run --resume %s\n", dir.c_str());
  }
  // A lost unit makes the exit 1 with the run completed: say which, --quiet or not.
  for (const auto& u : r.units) {
    if (!u.loss) continue;
    std::printf("unit %s: lost (%s)%s: %s\n", u.serial.c_str(), to_string(u.loss->cause),
                u.loss->point >= 0 ? fmt::format(" at point {}", u.loss->point + 1).c_str() : " before the first point",
                u.loss->reason.c_str());
  }
  if (!r.catalogue_error.empty()) {
    print_error(fmt::format("run: {}\nhint: the run folder {} is complete; re-index it with: fpss-stand catalogue "
                            "rebuild --runs-dir {} --catalogue {}",
                            r.catalogue_error, dir, r.run_dir.parent_path().string(),
                            req.catalogue.empty() ? (r.run_dir.parent_path() / "stand.db").string()
                                                  : url_for_messages(req.catalogue)));
  }
  if (r.calibration) std::printf("calibration: %s\n", r.calibration->string().c_str());
  if (r.report) std::printf("report: %s\n", r.report->string().c_str());
  std::fflush(stdout);
  return r.exit_code;
}

}  // namespace

void add_run(CLI::App& app, Runner& run) {
  auto a = std::make_shared<RunArgs>();
  auto* sub = app.add_subcommand("run", "Run a calibration procedure on a stand (or the emulated bench) and record it");
  expect_file(sub, sub->add_option("procedure", a->procedure, "Procedure file (YAML, docs/procedures.md)"), a->procedure,
              FileKind::procedure);
  add_bench_choice_options(sub, *a, "Stand file (YAML): endpoints, unit, limits, axes, timing",
                           "Start the emulated bench as a child process and run on it");
  sub->add_option("--unit,--unit-serial", a->unit_serial,
                  "Serial of the unit: with --emulate the serial the sensor reports, with --stand the one it must report");
  sub->add_option("--runs-dir", a->runs_dir, "Where run folders are made (default runs/)");
  expect_file(sub,
              sub->add_option("--resume", a->resume,
                              "Continue an interrupted run: its folder, or its id within --runs-dir (a unique prefix, or latest)"),
              a->resume,
              FileKind::run_folder);
  sub->add_flag("--dry-run", a->dry_run, "Validate, print the expanded steps, points and duration; move nothing");
  add_catalogue_option(sub, a->catalogue);
  add_catalogue_wait_option(sub, a->catalogue_wait_s);
  add_progress_options(sub, a->progress, a->no_progress);
  sub->add_flag("--quiet", a->quiet, "No log lines on the console, the libraries' included (events.log keeps them)");
  sub->add_option("--operator", a->operator_name, "Who runs it (recorded in run.json)");
  examples(sub, {"fpss-stand run procedures/discrete_grid.yaml --emulate --runs-dir runs",
                 "fpss-stand run procedures/discrete_grid.yaml --stand procedures/example_stand.yaml --dry-run"});
  sub->callback([&run, a] { run = [a] { return run_command(*a); }; });
}

}  // namespace fpss::cli
