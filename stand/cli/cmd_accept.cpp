// fpss-stand accept: acceptance of a unit (or of every unit of a pass) against its limits, certified.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/clock.h"
#include "base/errors.h"
#include "base/json_file.h"
#include "base/text_file.h"
#include "calib/coefficients.h"
#include "calib/compare.h"
#include "fixtures/bench.h"
#include "procedures/plan.h"
#include "procedures/recorder.h"
#include "stand/acceptance/acceptance.h"
#include "stand/catalogue/run_file.h"
#include "stand/catalogue/catalogue.h"
#include "stand/cli/catalogue_option.h"
#include "stand/cli/commands.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"
#include "stand/cli/emulated_bench.h"
#include "stand/cli/terminal.h"
#include "stand/config/stand_config.h"
#include "stand/report/compare_plot.h"
#include "stand/report/report.h"
#include "stand/report/units_page.h"
#include "stand/session/session.h"

extern char** environ;

namespace fpss::cli {
namespace fs = std::filesystem;
namespace {

// ---- accept ----

struct AcceptArgs : BenchChoiceArgs {
  std::string unit, procedure, limits, runs_dir = "runs", catalogue;
  bool json = false, quiet = false, progress = false, no_progress = false, operator_prompts = false;
  double catalogue_wait_s = 120;
};

// The page when the run's own report cannot be drawn (no calibration): the certificate alone.
std::string standalone_page(const std::string& title, const std::string& section_html, const std::string& why) {
  return fmt::format(
      "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{0}</title>"
      "<style>body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;"
      "padding:3px 6px;vertical-align:top}}</style></head>\n<body>\n<h1>{0}</h1>\n<p>{1}</p>\n"
      "<section id=\"acceptance\"><h2>Acceptance</h2>\n{2}</section>\n</body></html>\n",
      html_escape(title), html_escape(why), section_html);
}

// What an acceptance runs, checked before anything moves: limits, procedure and its roles, stand, bench.
struct AcceptancePlan {
  AcceptanceLimits limits;
  fs::path procedure_path;
  SessionRequest req;
  Plan plan;
  std::map<int64_t, PointRole> roles;
};

AcceptancePlan plan_acceptance(const AcceptArgs& a) {
  if (a.stand_file.empty() && !a.emulate) {
    throw InputError("accept: give --stand STAND.yaml --unit SERIAL for a real bench, or --emulate");
  }
  if (!a.emulate) {
    if (a.unit.empty()) throw InputError("accept --stand: give --unit SERIAL, the unit being accepted");
    require_emulate_for_options(a.emu, "accept");
  }
  AcceptancePlan p;
  p.limits = load_acceptance_limits(a.limits.empty() ? default_limits_path() : fs::path(a.limits));
  p.procedure_path = a.procedure.empty() ? default_acceptance_procedure_path() : fs::path(a.procedure);
  SessionRequest& req = p.req;
  req.runs_dir = a.runs_dir;
  req.quiet = a.quiet;
  if (::isatty(STDIN_FILENO)) req.keys_fd = STDIN_FILENO;  // p pause, r resume, a abort
  req.tty = draw_progress(a.progress, a.no_progress, a.quiet);
  const std::string proc = p.procedure_path.string();
  Diagnostics dp(proc);
  req.procedure = parse_procedure(read_text_file(p.procedure_path, "procedure file", kMaxConfigFileBytes), proc, dp);
  Diagnostics ds(a.stand_file);
  req.stand = stand_for_run(a.stand_file, a.emulate, a.emu.speed, ds);
  if (!a.unit.empty() && !a.emulate) req.stand.unit_serial = a.unit;
  req.catalogue = catalogue_url(a.catalogue, a.runs_dir, req.stand.catalogue);
  req.catch_up_s = a.catalogue_wait_s;
  if (dp.empty() && ds.empty()) p.plan = expand(req.procedure, req.stand.bench, dp);
  Diagnostics all(proc);
  all.merge(ds);
  all.merge(dp);
  all.throw_if_any();
  p.roles = acceptance_roles(req.procedure, p.plan);
  if (a.emulate) req.emulator = emulator_spec(a.emu, a.unit);
  req.write_report = false;  // drawn once, with the certificate (write_certificate_files)
  // The operator's prompts, answered through the run folder's control channel (docs/console.md).
  if (a.operator_prompts) {
    req.prompts = {{"serial", "Mount the unit, then scan or type its serial", PromptKind::serial},
                   {"lamp", "Sun simulator lamp on and stable?", PromptKind::confirm},
                   {"operator", "Your name (operator)", PromptKind::text}};
  }
  return p;
}

// The unit's reference calibration: the latest one that passed an acceptance on any stand sharing
// the catalogue, or was imported (a calibration done elsewhere); a failed acceptance's fit is no reference.
void find_reference(AcceptanceData& data, const std::string& url, const std::string& unit, const std::string& run_id) {
  const auto catp = open_catalogue(url);
  const Catalogue& cat = *catp;
  std::set<std::string> accepted_runs;
  for (const auto& acc : cat.unit_acceptances(unit)) {
    if (acc.passed && acc.run_id) accepted_runs.insert(*acc.run_id);
  }
  for (const auto& h : cat.unit_history(unit)) {
    if (h.run_id && *h.run_id == run_id) continue;
    if (h.source != "import" && !(h.run_id && accepted_runs.count(*h.run_id))) continue;
    try {
      data.previous = parse_coefficients(h.coefficients, fmt::format("{} calibration {}", cat.location(), h.id));
      data.previous_name = fmt::format("calibration {} of {} ({} {}{})", h.id, h.date_utc, h.source, h.source_ref,
                                       h.source == "import" ? "" : ", accepted");
    } catch (const InputError&) {
      // a record that does not parse cannot be compared; keep the one before
    }
  }
}

CertificateInfo certificate_info(const AcceptancePlan& p, const SessionResult& r, const RunFile& run,
                                 const std::string& unit) {
  const SessionRequest& req = p.req;
  CertificateInfo info;
  info.unit = unit;
  if (req.emulator) {
    info.stand = fmt::format("emulated bench (seed {}{}{}{})", req.emulator->seed,
                             req.emulator->bench_file.empty() ? "" : ", bench " + req.emulator->bench_file,
                             req.emulator->truth_file.empty() ? "" : ", truth " + req.emulator->truth_file,
                             req.emulator->effects.empty() ? "" : ", effects " + fmt::format("{}", fmt::join(req.emulator->effects, " ")));
    info.stand_detail = req.emulator->to_json();
  } else {
    info.stand = !req.stand.stand_id.empty() ? req.stand.stand_id : req.stand.origin;
    info.stand_detail = {{"file", req.stand.origin}, {"settings", to_json(req.stand)}};
  }
  info.procedure_name = req.procedure.name;
  info.procedure_file = fs::absolute(p.procedure_path).lexically_normal().string();
  info.procedure_sha256 = run.procedure.sha256;
  info.run_id = run.id_or(r.run_dir);
  info.run_dir = fs::absolute(r.run_dir).string();
  info.run_outcome = to_string(r.outcome);
  info.run_reason = r.reason;
  info.points_planned = static_cast<int64_t>(p.plan.points);
  info.points_completed = r.points_done;
  info.date_utc = utc_now_iso();
  info.calibration_file = r.calibration ? r.calibration->filename().string() : "";
  if (const auto& ref = req.stand.bench.reference) info.reference = ref->identity();
  return info;
}

// acceptance.json, certificate.txt and the report page with the certificate (the folder's report
// with it as a section, or the certificate alone), its banner `verdict`, in `dir`.
std::string write_certificate_files(const fs::path& dir, const nlohmann::ordered_json& cert, const RunVerdict& verdict,
                                    const std::string& title, const SampleTable& recording) {
  write_text_atomic(dir / "acceptance.json", cert.dump(1) + "\n");
  const std::string text = certificate_text(cert);
  write_text_atomic(dir / "certificate.txt", text);
  const std::string section = certificate_html(cert);
  try {
    ReportOptions ro;
    ro.extra_sections.push_back({"acceptance", "Acceptance", section});
    ro.verdict = verdict;
    ro.recording = &recording;
    write_report(dir, ro);
  } catch (const std::exception& e) {
    write_text_atomic(dir / "report.html",
                      standalone_page(title, verdict_banner_html(verdict) + section,
                                      fmt::format("The report could not be drawn: {}", e.what())));
  }
  return text;
}

// The run's own report, when no verdict comes (the session leaves report.html to accept).
void write_plain_report(const SessionResult& r) {
  if (!r.units.empty()) {  // several units: each one's own report, and the run's page
    try {
      std::vector<UnitFolder> folders;
      for (const auto& u : r.units) folders.push_back({u.dir, &u.recording});
      write_unit_reports(r.run_dir, read_run_file(r.run_dir), folders);
    } catch (const std::exception& e) {
      print_error(fmt::format("accept: report not written: {}", e.what()));
    }
    return;
  }
  if (!r.calibration) return;
  try {
    ReportOptions ro;
    ro.recording = &r.recording;
    write_report(r.run_dir, ro);
  } catch (const std::exception& e) {
    print_error(fmt::format("accept: report not written: {}", e.what()));
  }
}

// One unit's verdict, written and recorded.
struct UnitAcceptance {
  Judgement judgement;
  nlohmann::ordered_json cert;
  std::string text;
  int64_t acc_id = 0;
  bool recorded = true;  // the catalogue took it
};

// Judges one unit's recording and calibration, writes its certificate files into `dir` and records
// the verdict in the catalogue. The verdict goes into `entry` (several units: its run.json entry),
// else into `run`'s acceptance, written to run.json.
UnitAcceptance accept_unit(const AcceptancePlan& p, const SessionResult& r, RunFile& run, const std::string& unit,
                           const fs::path& dir, SampleTable recording, const std::optional<fs::path>& calibration,
                           RunFileUnit* entry) {
  const bool completed = r.outcome == RunOutcome::completed;
  AcceptanceData data;
  data.roles = p.roles;
  data.points_planned = p.plan.points;
  data.run_completed = completed;
  data.run_reason = r.reason;
  data.samples = std::move(recording);  // the session's recording: samples.csv is not read again
  if (calibration && fs::exists(*calibration)) data.calibration = load_coefficients(*calibration);
  data.reference = p.req.stand.bench.reference;
  data.mount = p.req.stand.bench.axes;
  for (const StandUnit& su : p.req.stand.units) {
    if (su.serial == unit) data.mount = su.axes;
  }
  const std::string cat_url = p.req.catalogue;
  const std::string run_id = run.id_or(r.run_dir);
  find_reference(data, cat_url, unit, run_id);

  UnitAcceptance out{judge(data, p.limits), {}, {}, 0, true};
  const Judgement& j = out.judgement;
  CertificateInfo info = certificate_info(p, r, run, unit);
  if (calibration) info.calibration_file = fs::relative(*calibration, r.run_dir).string();
  // The calibrated angle's figures as calibration.json has them (loaded once, above).
  if (data.calibration) {
    info.calibration_uncertainty = calibration_uncertainty(data.calibration->extra.value("uncertainties", nlohmann::json()));
  }
  out.cert = certificate_json(j, p.limits, info);
  if (r.answers.count("operator")) {
    out.cert["operator"] = r.answers.at("operator");
    out.cert["signed_off_utc"] = r.signed_off_utc;
  }
  const std::string title = fmt::format("Acceptance of {} ({})", unit, run_id);
  RunVerdict verdict;
  if (entry) {
    entry->acceptance = fs::relative(dir / "acceptance.json", r.run_dir).string();
    entry->certificate = fs::relative(dir / "certificate.txt", r.run_dir).string();
    entry->verdict = to_string(j.outcome);
    verdict = unit_verdict(run, *entry);
  } else {
    RunFileAcceptance acc;
    acc.file = "acceptance.json";
    acc.certificate = "certificate.txt";
    acc.verdict = to_string(j.outcome);
    acc.failed = j.failed();
    acc.limits = RunFileAcceptance::Limits{p.limits.origin, p.limits.sha256};
    run.acceptance = acc;
    write_run_file(r.run_dir, run);
    verdict = run_verdict(run);
  }
  out.text = write_certificate_files(dir, out.cert, verdict, title, data.samples);
  try {
    const auto cat = open_catalogue(cat_url);
    AcceptanceRecord rec;
    rec.unit = unit;
    rec.run_id = run_id;
    rec.passed = j.passed;
    rec.date_utc = info.date_utc;
    rec.certificate = nlohmann::json::parse(out.cert.dump());
    rec.stand = p.req.stand.stand_id;
    rec.operator_name = run.operator_name.value_or(out.cert.value("operator", ""));
    out.acc_id = cat->record_acceptance(rec);
  } catch (const std::exception& e) {
    // The folder holds the verdict; its mark lets the next run or `catalogue rebuild` index it.
    try {
      mark_catalogue_pending(r.run_dir, url_for_messages(cat_url), "acceptance", e.what());
    } catch (const std::exception&) {
    }
    print_error(fmt::format("accept: verdict {} written to {}, but the catalogue {} could not record it: {}",
                            to_string(j.outcome), (dir / "acceptance.json").string(), url_for_messages(cat_url), e.what()));
    out.recorded = false;
  }
  return out;
}

int exit_code_of(const Judgement& j) {
  return j.passed ? exit_code::ok : j.outcome == Outcome::fail ? exit_code::acceptance_failed : exit_code::acceptance_conditional;
}

// Several units: a verdict per unit that completed; a lost unit has none (its outcome names the
// loss). Exit 1 when any unit has no verdict, else 3 when any failed, 4 when any is conditional.
int accept_units(const AcceptArgs& a, const AcceptancePlan& p, SessionResult& r) {
  RunFile run = read_run_file(r.run_dir);
  int code = 0;
  nlohmann::ordered_json all = nlohmann::ordered_json::array();
  for (size_t i = 0; i < r.units.size(); ++i) {
    SessionResult::Unit& u = r.units[i];
    RunFileUnit& ru = run.units->at(i);
    if (u.loss || !u.calibration) {
      std::printf("unit %s: no verdict (%s)\n", u.serial.c_str(), u.loss ? ("lost: " + u.loss->reason).c_str() : "no calibration");
      code = 1;
      continue;
    }
    const UnitAcceptance ua = accept_unit(p, r, run, u.serial, u.dir, std::move(u.recording), u.calibration, &ru);
    if (!ua.recorded) code = 1;
    const int c = exit_code_of(ua.judgement);
    if (code != 1 && (c == 3 || (c == 4 && code == 0))) code = c;
    if (a.json) {
      all.push_back({{"unit", u.serial}, {"certificate", ua.cert}});
    } else {
      std::printf("%s\nunit %s: acceptance %s: %s\n", ua.text.c_str(), u.serial.c_str(),
                  ua.judgement.passed ? "PASSED" : ua.judgement.outcome == Outcome::fail ? "FAILED" : "CONDITIONAL",
                  (u.dir / "acceptance.json").c_str());
    }
  }
  write_run_file(r.run_dir, run);
  std::vector<UnitReport> pages;
  for (size_t i = 0; i < r.units.size(); ++i) {
    const fs::path own = r.units[i].dir / "report.html";
    pages.push_back({run.units->at(i), unit_verdict(run, run.units->at(i)),
                     fs::exists(own) ? std::optional<fs::path>(own) : std::nullopt});
  }
  const fs::path page = write_units_report(r.run_dir, run, pages);
  if (a.json) std::printf("%s\n", all.dump(1).c_str());
  else std::printf("report: %s\n", page.c_str());
  std::fflush(stdout);
  return code;
}

int accept_command(const AcceptArgs& a) {
  const AcceptancePlan p = plan_acceptance(a);
  SessionResult r = run_session(p.req);
  const fs::path run_dir = r.run_dir;
  const bool completed = r.outcome == RunOutcome::completed;
  // A unit that gives invalid frames (no Sun, an axis invalid, saturated) stops the run: that is
  // the unit failing, judged below. Any other stop is the stand's: no verdict.
  const bool unit_stopped = r.outcome == RunOutcome::failed && r.cause == StopCause::sensor_invalid;
  if (!completed && !unit_stopped) {
    print_error(fmt::format("accept: the run {}: {}\nno verdict; the run folder is {}", to_string(r.outcome), r.reason,
                            run_dir.string()));
    write_plain_report(r);
    return 1;
  }
  if (!r.units.empty()) return accept_units(a, p, r);

  RunFile run = read_run_file(run_dir);
  const std::string unit = run.unit.empty() ? a.unit : run.unit;
  const std::optional<fs::path> calibration = r.calibration;
  const UnitAcceptance ua = accept_unit(p, r, run, unit, run_dir, std::move(r.recording), calibration, nullptr);
  if (!ua.recorded) return 1;
  const Judgement& j = ua.judgement;
  const std::string cat_url = p.req.catalogue;
  if (a.json) {
    std::printf("%s\n", ua.cert.dump(1).c_str());
  } else {
    std::printf("%s\n", ua.text.c_str());
    std::printf("acceptance %s: %s\ncertificate: %s\nreport: %s\ncatalogue: %s (acceptance %lld)\n",
                j.passed ? "PASSED" : j.outcome == Outcome::fail ? "FAILED" : "CONDITIONAL", (run_dir / "acceptance.json").c_str(),
                (run_dir / "certificate.txt").c_str(), (run_dir / "report.html").c_str(), url_for_messages(cat_url).c_str(),
                static_cast<long long>(ua.acc_id));
  }
  std::fflush(stdout);
  // Conditional is no acceptance (exit 4, catalogue passed = false), nor a failure (exit 3).
  return exit_code_of(j);
}

void add_accept_command(CLI::App& app, Runner& run) {
  auto a = std::make_shared<AcceptArgs>();
  auto* sub = app.add_subcommand(
      "accept", "Acceptance of a sensor unit: calibrate, verify on unseen points, measure jitter, judge, certify " +
                    fmt::format("(exit {} pass, {} fail, {} conditional)", exit_code::ok, exit_code::acceptance_failed,
                                exit_code::acceptance_conditional));
  add_bench_choice_options(sub, *a, "Stand file (YAML) of a real bench",
                           "Run on the emulated bench (a child process over the real wire)");
  sub->add_option("--unit,--unit-serial", a->unit, "Serial of the unit (required with --stand; with --emulate, the serial it reports)");
  expect_file(sub, sub->add_option("--procedure", a->procedure, "Acceptance procedure (default procedures/acceptance.yaml)"),
              a->procedure, FileKind::procedure);
  expect_file(sub, sub->add_option("--limits", a->limits, "Acceptance limits (default procedures/acceptance_limits.yaml)"),
              a->limits, FileKind::limits);
  sub->add_option("--runs-dir", a->runs_dir, "Where run folders are made")->capture_default_str();
  add_catalogue_option(sub, a->catalogue);
  add_catalogue_wait_option(sub, a->catalogue_wait_s);
  sub->add_flag("--json", a->json, "Print acceptance.json instead of the certificate text");
  sub->add_flag("--quiet", a->quiet, "No log lines on the console, the libraries' included (events.log keeps them)");
  add_progress_options(sub, a->progress, a->no_progress);
  sub->add_flag("--operator-prompts", a->operator_prompts,
                "Ask the operator (unit serial, lamp, name) through the run folder's control channel: the web console");
  examples(sub, {"fpss-stand accept --emulate --unit FPSS1-SN042 --runs-dir runs",
                 "fpss-stand accept --stand procedures/example_stand.yaml --unit FPSS1-SN042"});
  sub->callback([&run, a] { run = [a] { return accept_command(*a); }; });
}

}  // namespace

void add_accept(CLI::App& app, Runner& run) {
  add_accept_command(app, run);
}

}  // namespace fpss::cli
