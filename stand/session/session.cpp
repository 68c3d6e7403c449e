#include "stand/session/session.h"

#include <signal.h>
#include <unistd.h>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <limits>
#include <optional>
#include <variant>
#include <fstream>
#include <sstream>

#include "base/clock.h"
#include "base/errors.h"
#include "calib/calibrator.h"
#include "calib/report.h"
#include "calib/streaming.h"
#include "calib/transfer_function.h"
#include "calib/unit_alignment.h"
#include "drivers/endpoints.h"
#include "procedures/recorder.h"
#include "stand/catalogue/catalogue.h"
#include "stand/report/report.h"
#include "stand/report/units_page.h"
#include "stand/session/bench_launcher.h"
#include "stand/session/catch_up.h"
#include "stand/session/diagnose_step.h"
#include "stand/session/emulator_process.h"
#include "stand/session/live_fit.h"
#include "stand/session/progress.h"
#include "stand/session/run_folder.h"
#include "stand/session/run_record.h"
#include "stand/session/session_units.h"
#include "stand/session/signals.h"
#include "stand/session/terminal_keys.h"

namespace fpss {

namespace fs = std::filesystem;

std::string serial_from_id(const std::string& id) {
  const auto p = id.find("SN=");
  if (p == std::string::npos) return id;
  const auto e = id.find(',', p);
  return id.substr(p + 3, e == std::string::npos ? std::string::npos : e - p - 3);
}

namespace {

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The session

namespace {

class Session {
 public:
  explicit Session(const SessionRequest& req) : req_(req), resuming_(!req.resume_dir.empty()) {}
  SessionResult run();

 private:
  void make_logger();
  void connect_devices();
  void open_folder();
  void write_start_record();
  void start_catalogue_record();
  void subscribe();
  void on_point_done(const PointDone& p);
  void on_step_stopped(const StepStopped& s);
  void publish_live_fit(int64_t points, bool force = true, const std::vector<Sample>& rows = {});
  template <typename F>
  void live_guarded(F&& f);  // f() on the live fit, which is switched off if it throws
  int64_t points_before(const Action& a) const;  // points planned before a computation step
  void ask_prompts(ControlPoller& poller, RunControl& control);
  void on_calibrate(const Action& a);
  void on_diagnose(const Action& a);
  CheckReport on_check(const Action& a);
  void finish(const EngineResult& er);
  void write_report();
  template <typename F>
  void with_catalogue(const char* what, F&& f);

  const SessionRequest& req_;
  const bool resuming_;
  SessionResult res_;
  Plan plan_;
  std::shared_ptr<spdlog::logger> log_;
  RunInfo prior_;
  StandConfig stand_;
  BenchLauncher bench_;
  std::unique_ptr<Gimbal> gimbal_;
  std::vector<SessionUnit> units_;  // the stand's, in order; units_[0] is the single unit of a one-unit run
  std::string unit_, run_id_;     // unit_: the run's name for its unit(s)
  bool multi() const { return units_.size() > 1; }
  void calibrate_unit(const Action& a, SessionUnit& u);
  void write_unit_reports();
  std::optional<RunFolderLock> lock_;
  std::unique_ptr<RunRecorder> rec_;
  std::unique_ptr<EventLog> event_log_;
  EventBus bus_;
  RunFile run_;  // run.json
  int session_ = 1;
  std::string catalogue_url_;
  std::string catalogue_error_;
  bool catalogue_away_ = false;  // the server was unreachable (worth waiting for), not a refusal
  std::unique_ptr<LiveFit> live_;
  std::unique_ptr<Progress> progress_;
  int calibrations_ = 0;
  int diagnoses_ = 0;
  std::vector<std::string> after_progress_;  // a terminal: Table 1 and the check, shown once the live line is done
};

void Session::make_logger() {
  // Console logging first; the run folder's events.log joins once the folder exists.
  auto console = std::make_shared<spdlog::sinks::stderr_sink_mt>();
  console->set_level(req_.quiet ? spdlog::level::off : req_.tty ? spdlog::level::warn : spdlog::level::info);
  console->set_pattern("fpss-stand run: %v");
  log_ = std::make_shared<spdlog::logger>("run", spdlog::sinks_init_list{console});
  log_->set_level(spdlog::level::debug);
  log_->flush_on(spdlog::level::info);
}

void Session::connect_devices() {
  stand_.gimbal.limits = stand_.bench.limits;
  gimbal_ = make_gimbal(stand_.gimbal);
  gimbal_->connect();
  if (stand_.units.size() <= 1) stand_.sync_first_unit();  // one unit: its fields may have been set by a caller
  units_ = connect_units(stand_, *log_);
  unit_ = units_name(units_);
  if (resuming_ && prior_.run.unit != unit_) {
    throw InputError(fmt::format("{}: the run was made on unit \"{}\", the sensor now reports \"{}\"",
                                 req_.resume_dir.string(), prior_.run.unit, unit_));
  }
}

void Session::open_folder() {
  const std::string now_utc = utc_now_iso();
  if (resuming_) {
    res_.run_dir = req_.resume_dir;  // locked and canonical already
    run_ = prior_.run;
    session_ = static_cast<int>(run_.sessions.size()) + 1;
  } else {
    res_.run_dir = make_run_dir(req_.runs_dir, now_utc, unit_, req_.procedure.name);
    lock_.emplace(res_.run_dir);
    bench_.settle_log(res_.run_dir);
  }
  // A fleet-wide id (UUIDv7); a run made before ids were one keeps its folder's name.
  run_id_ = resuming_ ? run_.run_id.value_or(res_.run_dir.filename().string()) : new_run_id();
  auto file_sink = std::make_shared<spdlog::sinks::basic_file_sink_mt>((res_.run_dir / "events.log").string());
  file_sink->set_pattern("%Y-%m-%dT%H:%M:%S.%e [%l] %v");
  log_->sinks().push_back(file_sink);
  log_->info("run {} session {}: procedure {} ({}), unit {}, {}", run_id_, session_, req_.procedure.name,
             req_.procedure.origin, unit_, req_.emulator ? "emulated bench" : "stand " + stand_.stand_id);
  rec_ = std::make_unique<RunRecorder>(res_.run_dir, unit_serials(units_));
  if (rec_->cut_bytes() > 0) {
    log_->warn("samples.csv: cut {} bytes of a point that never completed (it is measured again)", rec_->cut_bytes());
  }
  event_log_ = std::make_unique<EventLog>(res_.run_dir / "events.jsonl");
  open_recordings(units_, *rec_);
}

void Session::write_start_record() {
  const std::string now_utc = utc_now_iso();
  if (!resuming_) {
    run_ = RunFile{};
    run_.format = kRunFileFormat;
    run_.run_id = run_id_;
    run_.software = RunFile::Software{"fpss-stand", FPSS_VERSION};
    run_.procedure = {req_.procedure.name, sha256_hex(req_.procedure.text), req_.procedure.text, req_.procedure.origin};
    run_.stand = RunFile::Stand{stand_.origin.empty() ? std::nullopt : std::optional(stand_.origin),
                                stand_.text.empty() ? std::nullopt : std::optional(stand_.text), to_json(stand_)};
    run_.unit = unit_;
    run_.sensor_id = units_.front().id_reply;
    if (multi()) run_.units = unit_entries(units_, *rec_, res_.run_dir);
    run_.emulated = req_.emulator.has_value();
    if (req_.emulator) run_.emulator = req_.emulator->to_json();
    run_.started_utc = now_utc;
    run_.points = {static_cast<int64_t>(plan_.points), 0, std::nullopt};
    run_.files = {fs::relative(rec_->samples_path(), res_.run_dir).string(), "points.jsonl", "events.log", "events.jsonl",
                  std::nullopt, std::nullopt};
    if (const auto& ref = stand_.bench.reference) {
      run_.reference = RunFileReference{ref->file, ref->sha256, ref->certificate, ref->date, ref->lab};
    }
  }
  if (!req_.operator_name.empty()) run_.operator_name = req_.operator_name;
  run_.outcome = "running";
  run_.ended_utc.reset();
  run_.reason.reset();
  run_.stop_cause.reset();
  RunFileSession sess;
  sess.session = session_;
  sess.started_utc = now_utc;
  sess.first_point = rec_->next_point() + 1;
  sess.pid = ::getpid();
  if (const EmulatorProcess* bench = bench_.bench()) {
    sess.emulator = nlohmann::json{{"command", bench->command()}, {"gimbal", stand_.gimbal.endpoint},
                                   {"sensor", stand_.sensor.endpoint}};
    if (bench_.borrowed) sess.emulator->operator[]("shared") = true;  // the bench went on before and after
    if (multi()) sess.emulator->operator[]("sensors") = bench->sensor_endpoints();
  }
  run_.sessions.push_back(sess);
  write_run_file(res_.run_dir, run_);
}

// A catalogue that cannot record never loses the run (the folder is complete), but the command
// says so and ends with exit 1; `fpss-stand catalogue rebuild` re-indexes the folder later.
// A catalogue that is away marks the folder pending; the run end catches up (catch_up.h).
template <typename F>
void Session::with_catalogue(const char* what, F&& f) {
  try {
    auto cat = open_catalogue(catalogue_url_);
    f(*cat);
  } catch (const std::exception& e) {
    catalogue_away_ |= dynamic_cast<const CatalogueUnavailable*>(&e) != nullptr;
    const std::string shown = url_for_messages(catalogue_url_);
    log_->error("catalogue {}: {}: {}", shown, what, e.what());
    if (catalogue_error_.empty()) catalogue_error_ = fmt::format("catalogue {}: {}: {}", shown, what, e.what());
    try {
      mark_catalogue_pending(res_.run_dir, shown, what, e.what());
    } catch (const std::exception& m) {
      log_->error("{}: {}", kCataloguePending, m.what());
    }
  }
}

void Session::start_catalogue_record() {
  catalogue_url_ = !req_.catalogue.empty() ? req_.catalogue
                   : resuming_            ? (res_.run_dir.parent_path() / "stand.db").string()
                                          : Catalogue::default_path(req_.runs_dir).string();
  with_catalogue("run start", [&](Catalogue& cat) {
    cat.record_run_start({.run_id = run_id_, .unit = unit_, .procedure = req_.procedure.name,
                          .procedure_hash = run_.procedure.sha256, .started_utc = run_.started_utc,
                          .run_dir = fs::absolute(res_.run_dir), .emulated = req_.emulator.has_value(),
                          .stand = !stand_.stand_id.empty() ? stand_.stand_id : req_.emulator ? "" : stand_.origin,
                          .operator_name = run_.operator_name.value_or("")});
  });
}

// The subscribers, in order: the recorder (durable first), the rows kept in memory for calibrate
// steps, events.jsonl, then the live fit and the progress line.
void Session::subscribe() {
  record_with(bus_, *rec_);
  bus_.subscribe([this](const Event& e) {
    if (const auto* s = std::get_if<Samples>(&e)) {
      for (const auto& r : *s->rows) units_.at(static_cast<size_t>(r.unit)).recorded.push_back(r.sample, r.provenance());
    }
  });
  bus_.subscribe([this](const Event& e) { event_log_->write(e); });
  try {
    live_ = std::make_unique<LiveFit>(plan_, stand_.bench.axes);
  } catch (const std::exception& e) {
    log_->warn("live residual off: {}", e.what());
  }
  live_guarded([&] {
    const SampleTable& first = units_.front().recorded;  // several units: the live fit follows the first
    for (size_t i = 0; i < first.size(); ++i) live_->add(first.row(i));
  });
  progress_ = std::make_unique<Progress>(plan_.points, static_cast<size_t>(rec_->next_point()), req_.tty, *log_);
  bus_.subscribe([this](const Event& e) {
    if (const auto* p = std::get_if<PointDone>(&e)) on_point_done(*p);
    if (const auto* s = std::get_if<StepStopped>(&e)) on_step_stopped(*s);
  });
}

void Session::on_point_done(const PointDone& p) {
  // The estimate costs a few thousand small solves: refreshed twice a second at most (on the live
  // fit's own thread), and always after the last point.
  std::vector<Sample> rows;
  rows.reserve(p.rows->size());
  for (const auto& r : *p.rows) {
    if (r.unit == 0) rows.push_back(r.sample);
  }
  publish_live_fit(p.point.index + 1, progress_->done() + 1 >= plan_.points, rows);
  // Each point against the latest live fit, for the console's residual chart and map.
  live_guarded([&] {
    for (const auto& r : live_->residuals(p.point.index + 1, p.stats)) {
      event_log_->write_note("point_residual", {{"point", r.point}, {"ref_pitch_arcsec", r.ref_pitch_arcsec},
                                                {"ref_yaw_arcsec", r.ref_yaw_arcsec},
                                                {"residual_pitch_arcsec", r.residual_pitch_arcsec},
                                                {"residual_yaw_arcsec", r.residual_yaw_arcsec}});
    }
  });
  progress_->point_done(live_ ? live_->text() : std::string());
}

void Session::publish_live_fit(int64_t points, bool force, const std::vector<Sample>& rows) {
  live_guarded([&] {
    if (auto f = live_->point_done(rows, points, force)) bus_.publish(*f);
  });
}

template <typename F>
void Session::live_guarded(F&& f) {
  if (!live_) return;
  try {
    f();
  } catch (const std::exception& e) {
    // The live fit is for the operator's eyes: the run goes on without it.
    log_->warn("live residual off: {}", e.what());
    live_.reset();
  }
}

void Session::on_step_stopped(const StepStopped& s) {
  if (!run_.adaptive_stops) run_.adaptive_stops.emplace();
  run_.adaptive_stops->push_back(RunFileAdaptiveStop::of(s));
  int64_t skipped = 0;
  for (const auto& st : *run_.adaptive_stops) skipped += st.points_skipped;
  run_.points.skipped = skipped;
  progress_->skipped(s.skipped.size());
  // The fit that stopped the step is always published, whatever the display's refresh rate: the
  // console and events.jsonl show the sigma that met the target.
  publish_live_fit(s.skipped.empty() ? 0 : s.skipped.front());
  progress_->note(s.reason() + fmt::format(" (step {}, {}: {} points not measured)", s.step_index, s.axes,
                                                      s.skipped.size()));
}

int64_t Session::points_before(const Action& a) const {
  int64_t n = 0;
  for (const auto& x : plan_.actions) {
    if (&x == &a) break;
    if (x.is_point()) ++n;
  }
  return n;
}

void Session::on_calibrate(const Action& a) {
  progress_->clear();
  ++calibrations_;
  res_.calibration.reset();
  for (SessionUnit& u : units_) {
    if (u.loss) continue;  // a lost unit's recording is cut short: nothing to certify
    calibrate_unit(a, u);
  }
  if (multi()) relate_units(units_, run_, *log_);
}

void Session::calibrate_unit(const Action& a, SessionUnit& u) {
  const SampleTable rows = u.recorded.up_to_step(points_before(a));
  const CalibrationOptions o = calibration_options(*a.calibrate, u, stand_.bench);
  const auto t0 = std::chrono::steady_clock::now();
  CalibrationReport rep = calibrate(rows, o);
  const fs::path out = u.dir / (calibrations_ == 1 ? std::string("calibration.json")
                                                    : fmt::format("calibration-{}.json", calibrations_));
  // The report's Table 1 counts the rows this fit saw, not the points measured after it (verification).
  CoefficientSet fitted = rep.coefficients();
  fitted.extra["fit_last_step"] = points_before(a);
  save_coefficients(out, fitted);
  log_->info("{}calibrated on {} rows of {} points in {:.2f} s -> {}\n{}", multi() ? "unit " + u.serial + ": " : "",
             rows.size(), points_before(a), seconds_since(t0), fs::relative(out, res_.run_dir).string(),
             summary_text(rep));
  if (req_.tty) after_progress_.push_back(summary_text(rep));
  u.calibration = out;
  if (!res_.calibration) res_.calibration = out;
  u.cal = rep;
  with_catalogue("calibration", [&](Catalogue& cat) {
    CalibrationRecord cr = CalibrationRecord::from_calibration_json(to_json(fitted), out.string());
    cr.unit = u.serial;
    cr.source = "run";
    cr.run_id = run_id_;
    cr.source_ref = run_id_;
    cr.date_utc = utc_now_iso();
    cr.stand = !stand_.stand_id.empty() ? stand_.stand_id : req_.emulator ? "" : stand_.origin;
    cr.operator_name = run_.operator_name.value_or("");
    cat.record_calibration(cr);
  });
}

void Session::on_diagnose(const Action& a) {
  progress_->clear();
  // The rows in memory hold every column samples.csv does (the provenance as numbers): the
  // diagnosis reads the same ones `fpss-stand diagnose --data` would, up to the last point before.
  const fs::path gap =
      diagnose_units(units_, points_before(a), *a.diagnose, res_.run_dir, ++diagnoses_, run_id_, *log_, req_.predict_followups);
  if (diagnoses_ == 1 && !gap.empty()) run_.files.gap = gap.filename().string();
}

CheckReport Session::on_check(const Action& a) {
  CheckReport report;
  for (const SessionUnit& u : units_) {
    if (u.loss) continue;
    if (!u.cal) {
      report.units.push_back({.unit = multi() ? u.serial : "", .calibrated = false});
      break;
    }
    UnitCheck c = check_calibration(*a.check, u.cal->pitch.residuals, u.cal->yaw.residuals, multi() ? u.serial : "");
    const std::string who = multi() ? "unit " + u.serial + " " : "";
    const std::string line = fmt::format("{}check: {}", who, c.passed() ? "residuals within the limits" : c.text());
    log_->info("{}", line);
    if (req_.tty) after_progress_.push_back(line);
    report.units.push_back(std::move(c));
  }
  return report;
}

void Session::finish(const EngineResult& er) {
  res_.outcome = er.outcome;
  res_.cause = er.cause;
  res_.reason = er.reason;
  res_.points_done = er.points_done;
  const std::string end_utc = utc_now_iso();
  run_.outcome = to_string(er.outcome);
  run_.stop_cause = er.cause;
  if (!er.reason.empty()) run_.reason = er.reason;
  run_.ended_utc = end_utc;
  run_.points.completed = er.points_done;
  res_.points_skipped = run_.points.skipped.value_or(0);
  run_.safe_state = er.safe_state;
  end_session_record(run_.sessions.back(), end_utc, er, res_.stats, plan_, units_.front().sensor.get());
  if (res_.calibration) run_.files.calibration = fs::relative(*res_.calibration, res_.run_dir).string();
  if (multi()) record_unit_outcomes(units_, er.outcome, res_.run_dir, run_);
  write_run_file(res_.run_dir, run_);
  with_catalogue("run end", [&](Catalogue& cat) { cat.record_run_end(run_id_, er.outcome, end_utc); });
  if (!catalogue_error_.empty()) {
    // The entry catches up from the folder, which holds everything, once the catalogue is back.
    const double window_s = catalogue_away_ ? req_.catch_up_s : 0;
    log_->warn("catalogue {}: catching up with the run folder (up to {:.0f} s)", url_for_messages(catalogue_url_), window_s);
    const std::string err = catch_up_run(catalogue_url_, res_.run_dir, window_s);
    if (err.empty()) {
      log_->info("catalogue {}: the run's entry caught up", url_for_messages(catalogue_url_));
      catalogue_error_.clear();
    } else {
      catalogue_error_ += fmt::format("; still failing after {:.0f} s: {}", window_s, err);
    }
  }
}

// The report needs a calibration (this session's or an earlier one's); a failure to draw it
// never fails the run: the recording is what matters.
void Session::write_report() {
  if (!req_.write_report) return;
  if (multi()) {
    write_unit_reports();
    return;
  }
  if (!fs::exists(res_.run_dir / "calibration.json")) return;
  try {
    const auto t0 = std::chrono::steady_clock::now();
    ReportOptions ro;
    ro.recording = &units_.front().recorded;
    res_.report = fpss::write_report(res_.run_dir, ro);
    log_->info("report: {} ({:.2f} s)", res_.report->string(), seconds_since(t0));
  } catch (const std::exception& e) {
    log_->warn("report not written: {}", e.what());
  }
}

// Several units: each unit's own report in its folder, and the run's page with a section and a
// banner per unit (stand/report/units_page.h).
void Session::write_unit_reports() {
  try {
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<UnitFolder> folders;
    for (const SessionUnit& u : units_) folders.push_back({u.dir, &u.recorded});
    res_.report = fpss::write_unit_reports(res_.run_dir, run_, folders);
    log_->info("report: {} ({:.2f} s)", res_.report->string(), seconds_since(t0));
  } catch (const std::exception& e) {
    log_->warn("report not written: {}", e.what());
  }
}

void Session::ask_prompts(ControlPoller& poller, RunControl& control) {
  if (req_.prompts.empty()) return;
  const OperatorAnswers got = ask_operator(req_.prompts, units_.front().serial, poller, control, *event_log_, *log_);
  if (!got.complete) return;  // aborted: the engine stops before it moves
  res_.answers = got.answers;
  res_.signed_off_utc = got.signed_off_utc;
  if (res_.answers.count("operator")) run_.operator_name = res_.answers["operator"];
  run_.signed_off_utc = res_.signed_off_utc;
  write_run_file(res_.run_dir, run_);
  if (res_.answers.count("operator")) {  // the run's catalogue entry started without it
    with_catalogue("operator", [&](Catalogue& cat) { cat.record_run_operator(run_id_, *run_.operator_name); });
  }
}

SessionResult Session::run() {
  const auto t_start = std::chrono::steady_clock::now();
  // From here on SIGINT/SIGTERM ask for a clean stop rather than killing the process, so a run
  // folder once made always says how its run ended.
  RunControl own;
  RunControl& control = req_.control ? *req_.control : own;
  std::optional<SignalScope> signals;
  if (!req_.control) signals.emplace(control);

  Diagnostics d(req_.procedure.origin);
  plan_ = expand(req_.procedure, req_.stand.bench, d);
  d.throw_if_any();
  res_.points_total = static_cast<int64_t>(plan_.points);
  make_logger();
  if (resuming_) {
    lock_.emplace(req_.resume_dir);  // before anything is started or written
    prior_ = read_run_info(req_.resume_dir);
    if (prior_.run.outcome == "completed") {
      throw InputError(fmt::format("{}: the run is already completed; nothing to resume", req_.resume_dir.string()));
    }
  }
  stand_ = req_.stand;
  bench_.start(req_, resuming_, stand_, *log_);
  connect_devices();
  open_folder();

  // The drivers log through spdlog's default logger: their retries belong in events.log too.
  struct DefaultLogger {
    std::shared_ptr<spdlog::logger> prev = spdlog::default_logger();
    explicit DefaultLogger(std::shared_ptr<spdlog::logger> l) { spdlog::set_default_logger(std::move(l)); }
    ~DefaultLogger() { spdlog::set_default_logger(prev); }
  } default_logger(log_);

  write_start_record();
  start_catalogue_record();
  if (catalogue_error_.empty() && !resuming_) {
    const int n = catch_up_pending(catalogue_url_, req_.runs_dir);  // earlier runs the catalogue missed
    if (n > 0) log_->info("catalogue {}: {} earlier run folder(s) caught up", url_for_messages(catalogue_url_), n);
  }
  subscribe();
  // The console's pause/resume/abort and prompt answers (RUN_DIR/control.json).
  ControlPoller poller(res_.run_dir, control);
  ask_prompts(poller, control);
  EngineHooks hooks;
  hooks.calibrate = [this](const Action& a) { on_calibrate(a); };
  hooks.check = [this](const Action& a) { return on_check(a); };
  hooks.diagnose = [this](const Action& a) { on_diagnose(a); };
  hooks.unit_lost = [this](const UnitLoss& l) { units_.at(static_cast<size_t>(l.unit)).loss = l; };
  hooks.until_sigma = [this](const Action& a) {
    return live_ ? live_->until_sigma(a) : std::numeric_limits<double>::infinity();
  };
  EngineResult er;
  {
    std::optional<TerminalKeys> keys;
    if (req_.keys_fd >= 0 && TerminalKeys::foreground(req_.keys_fd)) {
      keys.emplace(req_.keys_fd, control, [this](const std::string& what) {
        if (req_.tty) log_->info("operator: {}", what);  // events.log; the console shows the note
        progress_->note("operator: " + what);
      });
      progress_->note("keys: p pause, r resume, a abort to the safe state; Ctrl-C interrupts");
    }
    const std::vector<EngineUnit> live = engine_units(units_);
    Engine engine(*gimbal_, *live.front().sensor, stand_.bench, plan_, bus_, *log_, control, hooks, rec_->resume_point());
    if (multi()) engine.set_units(live);
    er = engine.run(session_);
    res_.stats = engine.stats();
  }
  progress_->finish();
  for (const auto& text : after_progress_) std::fprintf(stderr, "%s\n", text.c_str());
  try {
    for (SessionUnit& u : units_) {
      if (u.sensor) u.sensor->disconnect();
    }
    gimbal_->disconnect();
  } catch (const std::exception& e) {
    log_->warn("disconnect: {}", e.what());
  }
  if (bench_.emu) log_->info("emulated bench stopped (status {})", bench_.stop());
  finish(er);
  write_report();
  const int64_t skipped = run_.points.skipped.value_or(0);
  log_->info("run {}: {} ({} of {} points{}){}", run_id_, to_string(er.outcome), er.points_done, plan_.points,
             skipped ? fmt::format(", {} of them skipped by the adaptive stop", skipped) : "",
             er.reason.empty() ? "" : ": " + er.reason);
  res_.exit_code = er.outcome == RunOutcome::completed ? 0 : 1;
  // Several units: the run exits 0 only when every unit completed.
  for (const SessionUnit& u : units_) {
    if (u.loss) res_.exit_code = 1;
  }
  if (multi()) {
    for (const SessionUnit& u : units_) {
      log_->info("unit {}: {}", u.serial, u.loss ? fmt::format("lost ({}): {}", to_string(u.loss->cause), u.loss->reason)
                                                  : std::string(to_string(er.outcome)));
    }
  }
  if (!catalogue_error_.empty()) {
    res_.exit_code = 1;
    res_.catalogue_error = catalogue_error_;
  }
  res_.wall_s = seconds_since(t_start);
  if (multi()) {
    for (SessionUnit& u : units_) res_.units.push_back({u.serial, u.dir, u.calibration, u.loss, std::move(u.recorded)});
  } else {
    res_.recording = std::move(units_.front().recorded);
  }
  log_->flush();
  return res_;
}

}  // namespace

SessionResult run_session(const SessionRequest& req) { return Session(req).run(); }

}  // namespace fpss
