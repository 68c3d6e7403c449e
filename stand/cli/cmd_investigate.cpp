// fpss-stand investigate: run a procedure, diagnose it, and while look-alikes stay or a candidate
// is neither named nor bounded, design a follow-up, run it and diagnose every recording jointly.
#include <fmt/chrono.h>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <memory>
#include <optional>

#include "base/errors.h"
#include "base/text_file.h"
#include "calib/coefficients.h"
#include "drivers/gimbal.h"
#include "procedures/plan.h"
#include "procedures/procedure.h"
#include "stand/catalogue/run_file.h"
#include "stand/cli/catalogue_option.h"
#include "stand/cli/commands.h"
#include "stand/cli/emulated_bench.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"
#include "stand/config/stand_config.h"
#include "stand/investigate/followup_design.h"
#include "stand/investigate/investigation.h"
#include "stand/report/investigation_page.h"
#include "stand/session/emulator_process.h"
#include "stand/session/session.h"

namespace fpss::cli {
namespace {

namespace fs = std::filesystem;

struct InvestigateArgs : BenchChoiceArgs {
  std::string model, procedure, runs_dir = "runs", out, catalogue, from;
  int max_runs = 3;
  double materiality_arcsec = 0, max_bench_s = 0, calibrated_range_arcsec = 0;
  bool quiet = false;
};

// One run of the loop through the stand's session; on --emulate every run is on the one emulated
// bench the investigation started (`bench`), whose clock, temperature and drift go on between runs
// as a real bench's do.
InvestigationRun run_on_stand(const InvestigateArgs& a, const EmulatorProcess* bench, const fs::path& procedure,
                              int index) {
  SessionRequest req;
  req.runs_dir = a.runs_dir;
  req.quiet = a.quiet;
  const std::string text = read_text_file(procedure, "procedure file", kMaxConfigFileBytes);
  Diagnostics dp(procedure.string());
  req.procedure = parse_procedure(text, procedure.string(), dp);
  Diagnostics ds(a.stand_file);
  req.stand = stand_for_run(a.stand_file, a.emulate, a.emu.speed, ds);
  if (ds.empty()) expand(req.procedure, req.stand.bench, dp);
  Diagnostics all(procedure.string());
  all.merge(ds);
  all.merge(dp);
  all.throw_if_any();
  if (a.emulate) {
    req.emulator = emulator_spec(a.emu, "");
    req.emulator->exe = this_binary();
    req.running_bench = bench;
  }
  req.catalogue = chosen_catalogue(a.catalogue, req.stand.catalogue);
  SessionResult r;
  try {
    r = run_session(req);
  } catch (const LimitError&) {
    throw;  // an endpoint or a target refused before the wire: bad input
  } catch (const DeviceError& e) {
    // The bench did not answer before the run began: the investigation records it and ends there.
    InvestigationRun failed;
    failed.cause = StopCause::other;
    failed.reason = e.what();
    failed.points_done = 0;
    failed.device_failed_to_start = true;
    if (!a.quiet) std::printf("run %d: %s\n", index + 1, describe_stop(failed).c_str());
    return failed;
  }
  InvestigationRun out;
  out.run_dir = r.run_dir;
  out.samples = r.run_dir / "samples.csv";
  out.completed = r.outcome == RunOutcome::completed;
  out.cause = out.completed ? StopCause::none : r.cause;
  out.reason = r.reason;
  out.points_done = r.points_done;
  if (!a.quiet) {
    std::printf("run %d: %s -> %s\n", index + 1, describe_stop(out).c_str(), r.run_dir.c_str());
    std::fflush(stdout);
  }
  return out;
}

// `--from RUN_DIR`: a run made earlier (a `run`'s, an `accept`'s or an investigation's), whatever
// its outcome, as the loop's first run. InputError naming the option for what cannot be one.
InvestigationRun earlier_run(const fs::path& run_dir, std::string* procedure) {
  if (!fs::is_directory(run_dir)) throw InputError(fmt::format("--from {}: not a run folder", run_dir.string()));
  const RunFile run = read_run_file(run_dir);
  if (run.units) {
    throw InputError(fmt::format("--from {}: a run of several units (investigate follows one unit: diagnose --run "
                                 "it unit by unit)",
                                 run_dir.string()));
  }
  InvestigationRun r;
  r.run_dir = run_dir;
  r.samples = run_dir / run.files.samples.value_or("samples.csv");
  if (!fs::is_regular_file(r.samples)) {
    throw InputError(fmt::format("--from {}: the run has no recording ({} is missing)", run_dir.string(),
                                 r.samples.string()));
  }
  r.completed = run.outcome == "completed";
  r.cause = r.completed ? StopCause::none : run.stop_cause.value_or(StopCause::other);
  r.reason = run.reason.value_or(run.outcome == "running" ? "the run never ended (run.json says running)" : "");
  r.points_done = run.points.completed;
  if (run.acceptance) r.acceptance = run.acceptance->verdict;
  *procedure = run.procedure.file.value_or(run.procedure.name);
  return r;
}

// What the console shows of the investigation: a verdict only for a diagnosis that was made.
void print_investigation(const Investigation& inv, const fs::path& out_dir) {
  std::printf("investigation: %s (%s)\n", inv.stop_reason.c_str(), inv.stop_sentence.c_str());
  if (!inv.diagnosed()) {
    std::printf("no diagnosis: %s\n", inv.no_diagnosis.c_str());
  } else {
    std::printf("verdict: %s\ncause: %s", inv.final.verdict.c_str(), inv.final.cause.c_str());
    for (size_t k = 1; k < inv.final.causes.size(); ++k) std::printf(", then %s", inv.final.causes[k].name.c_str());
    std::printf("\n");
    for (const auto& c : inv.final.causes) std::printf("params: %s %s\n", c.name.c_str(), c.params.dump().c_str());
    for (const auto& s : inv.final.ambiguous) {
      std::printf("still ambiguous: %s\n", fmt::format("{}", fmt::join(s.members, " / ")).c_str());
    }
    if (!inv.unbounded.empty()) {
      std::printf("neither named nor bounded: %s\n", fmt::format("{}", fmt::join(inv.unbounded, ", ")).c_str());
    }
  }
  // A run that did not complete but was gone on from is named, so that its stop is not missed.
  for (size_t k = 0; k < inv.runs.size(); ++k) {
    if (!inv.runs[k].completed || !inv.runs[k].acceptance.empty()) {
      std::printf("run %zu: %s\n", k + 1, describe_stop(inv.runs[k]).c_str());
    }
  }
  std::printf("runs: %zu, bench time %.0f s first, %.0f s follow-ups\nreport: %s\n", inv.runs.size(), inv.first_bench_s,
              inv.followup_bench_s, (out_dir / "INVESTIGATION.html").c_str());
}

int investigate_command(const InvestigateArgs& a) {
  if (a.stand_file.empty() && !a.emulate) {
    throw InputError("investigate: give --stand STAND.yaml for a real bench or --emulate for the emulated one");
  }
  if (!a.emulate) require_emulate_for_options(a.emu, "investigate");
  InvestigationOptions o;
  o.model = load_coefficients(a.model);
  o.model_path = a.model;
  o.max_runs = a.max_runs;
  o.diagnosis.materiality_arcsec = a.materiality_arcsec;
  o.max_followup_s = a.max_bench_s;
  FollowupBench fb = followup_bench(a.stand_file, a.emu.bench);
  // The default range (the paper's), within the stand's soft limits, unless given.
  const SoftLimits& l = fb.settings.limits;
  const double within_limits = std::min({DiagnosisOptions{}.calibrated_range_arcsec, -l.pitch_min_arcsec,
                                         l.pitch_max_arcsec, -l.yaw_min_arcsec, l.yaw_max_arcsec});
  o.diagnosis.calibrated_range_arcsec =
      a.calibrated_range_arcsec > 0 ? a.calibrated_range_arcsec
                                    : std::clamp(within_limits, kMinCalibratedRangeArcsec, kMaxCalibratedRangeArcsec);
  o.settings = fb.settings;
  o.bench = std::move(fb.bench);
  std::optional<InvestigationRun> from;
  std::string from_procedure;
  if (!a.from.empty()) from = earlier_run(a.from, &from_procedure);
  const fs::path procedure = from                  ? fs::path(from_procedure)
                             : a.procedure.empty() ? shipped_procedures_dir() / "sim_to_real.yaml"
                                                   : fs::path(a.procedure);
  if (!from) load_procedure(procedure);  // every error before anything moves
  o.out_dir = a.out.empty() ? fs::path(a.runs_dir) / fmt::format("investigation-{:%Y%m%dT%H%M%SZ}",
                                                                     fmt::gmtime(std::time(nullptr)))
                            : fs::path(a.out);
  // One emulated bench for every run, its log beside INVESTIGATION.json.
  std::unique_ptr<EmulatorProcess> bench;
  if (a.emulate) {
    fs::create_directories(o.out_dir);
    EmulatorLaunch l;
    l.exe = this_binary();
    l.args = emulator_spec(a.emu, "").args();
    l.log = o.out_dir / "emulator.log";
    bench = std::make_unique<EmulatorProcess>(l);
    bench->start();
  }
  const Investigation inv = investigate(
      procedure, o, [&](const fs::path& p, int k) { return run_on_stand(a, bench.get(), p, k); }, from);
  if (bench) bench->stop();
  const nlohmann::ordered_json j = inv.to_json();
  write_text_atomic(o.out_dir / "INVESTIGATION.json", j.dump(1) + "\n");
  write_investigation_page(o.out_dir / "INVESTIGATION.html", j);
  print_investigation(inv, o.out_dir);
  if (inv.stopped_by_a_run()) return 1;
  return 0;
}

}  // namespace

void add_investigate(CLI::App& app, Runner& run) {
  auto a = std::make_shared<InvestigateArgs>();
  auto* sub = app.add_subcommand(
      "investigate", "Run, diagnose, and design and run follow-ups until every candidate effect is named or bounded");
  expect_file(sub, sub->add_option("--model", a->model, "the sim model: a coefficient file (JSON)")->required(),
              a->model, FileKind::coefficients);
  add_bench_choice_options(sub, *a, "Stand file (YAML) of the real bench",
                           "Run on one emulated bench (a child that serves every run, its clock going on between them)");
  auto* procedure_opt = sub->add_option("--procedure", a->procedure, "the first run (default: procedures/sim_to_real.yaml)");
  expect_file(sub, procedure_opt, a->procedure, FileKind::procedure);
  sub->add_option("--from", a->from,
                  "start from a run made earlier (a run folder: run's, accept's or an investigation's; whatever its "
                  "outcome) instead of making the first run")
      ->excludes(procedure_opt);
  sub->add_option("--max-runs", a->max_runs, "the first run and the follow-ups, at most (default 3)")
      ->check(CLI::Range(1, 10));
  sub->add_option("--runs-dir", a->runs_dir, "where run folders are made (default runs/)");
  sub->add_option("--out", a->out, "folder of INVESTIGATION.json, INVESTIGATION.html, GAP.json and the follow-ups "
                                   "(default RUNS_DIR/investigation-<UTC time>)");
  sub->add_option("--materiality-arcsec", a->materiality_arcsec,
                  "what is material (default: the first run's noise floor of one dwell mean)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--max-bench-s", a->max_bench_s, "bench time of one follow-up (default: half the first run's)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--calibrated-range-arcsec", a->calibrated_range_arcsec,
                  "the calibrated half-range a refitted transfer function must be measured over and follow-ups plan "
                  "within (default: 1512, or less within the stand's soft limits)")
      ->check(CLI::Range(kMinCalibratedRangeArcsec, kMaxCalibratedRangeArcsec));
  add_catalogue_option(sub, a->catalogue);
  sub->add_flag("--quiet", a->quiet, "no log lines on the console (each run's events.log keeps them)");
  examples(sub, {"fpss-stand investigate --model calib/data/published/a-6-fpss1.json --emulate --effect "
                 "time_skew:skew_s=0.004 --procedure procedures/discrete_grid.yaml --speed 50",
                 "fpss-stand investigate --model MODEL.json --stand procedures/example_stand.yaml --from RUN_DIR"});
  sub->callback([&run, a] { run = [a] { return investigate_command(*a); }; });
}

}  // namespace fpss::cli
