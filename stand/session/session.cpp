#include "stand/session/session.h"

#include <signal.h>
#include <unistd.h>

#include <fmt/format.h>
#include <spdlog/sinks/basic_file_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <fstream>
#include <sstream>

#include "calib/calibrator.h"
#include "calib/errors.h"
#include "calib/report.h"
#include "calib/streaming.h"
#include "drivers/endpoints.h"
#include "stand/catalogue/catalogue.h"
#include "stand/session/emulator_process.h"
#include "stand/session/progress.h"
#include "stand/report/report.h"
#include "procedures/recorder.h"

namespace fpss {

namespace fs = std::filesystem;

std::string serial_from_id(const std::string& id) {
  const auto p = id.find("SN=");
  if (p == std::string::npos) return id;
  const auto e = id.find(',', p);
  return id.substr(p + 3, e == std::string::npos ? std::string::npos : e - p - 3);
}

RunInfo read_run_info(const fs::path& run_dir) {
  const fs::path path = run_dir / "run.json";
  if (!fs::exists(path)) throw InputError(fmt::format("{}: not a run folder (no run.json)", run_dir.string()));
  RunInfo info;
  info.doc = read_json_file(path);
  try {
    const auto& p = info.doc.at("procedure");
    info.procedure_text = p.at("text").get<std::string>();
    info.procedure_origin = p.value("file", "procedure.yaml");
    const std::string hash = p.at("sha256").get<std::string>();
    if (sha256_hex(info.procedure_text) != hash) {
      throw InputError(fmt::format("{}: the procedure text does not match its recorded hash", path.string()));
    }
    const auto& s = info.doc.at("stand");
    if (s.contains("text") && s["text"].is_string()) info.stand_text = s["text"].get<std::string>();
    if (s.contains("file") && s["file"].is_string()) info.stand_origin = s["file"].get<std::string>();
    if (info.doc.value("emulated", false)) {
      info.emulator = EmulatorSpec::from_json(info.doc.at("emulator"), path.string());
    }
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("{}: {}", path.string(), e.what()));
  }
  return info;
}

// ---------------------------------------------------------------------------------------------
// Signals

namespace {

RunControl* g_control = nullptr;

extern "C" void on_signal(int sig) {
  if (!g_control) return;
  if (sig == SIGUSR1) {
    g_control->pause.store(!g_control->pause.load());
    return;
  }
  g_control->signal.store(sig);
  g_control->abort.store(true);
}

class SignalScope {
 public:
  explicit SignalScope(RunControl& c) {
    g_control = &c;
    struct sigaction sa {};
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;  // no SA_RESTART: a blocking wait returns and the engine looks at the flag
    ::sigaction(SIGINT, &sa, &old_int_);
    ::sigaction(SIGTERM, &sa, &old_term_);
    ::sigaction(SIGUSR1, &sa, &old_usr1_);
  }
  ~SignalScope() {
    ::sigaction(SIGINT, &old_int_, nullptr);
    ::sigaction(SIGTERM, &old_term_, nullptr);
    ::sigaction(SIGUSR1, &old_usr1_, nullptr);
    g_control = nullptr;
  }

 private:
  struct sigaction old_int_ {}, old_term_ {}, old_usr1_ {};
};

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// The rows of the points before a calibrate step: what it may fit.
SampleTable rows_up_to(const SampleTable& all, int64_t last_step) {
  SampleTable t;
  t.origin = all.origin;
  t.reserve(all.size());
  for (size_t i = 0; i < all.size() && all.step[i] <= last_step; ++i) t.push_back(all.row(i));
  return t;
}

std::string check_limits(const ResidualLimits& lim, const ResidualStats& r, const char* axis) {
  std::string broken;
  auto add = [&](std::string s) { broken += (broken.empty() ? "" : "; ") + s; };
  if (lim.mean_abs_arcsec && r.mean_abs_arcsec > *lim.mean_abs_arcsec) {
    add(fmt::format("{} mean |residual| {:.3f} arcsec > {} arcsec", axis, r.mean_abs_arcsec, *lim.mean_abs_arcsec));
  }
  if (lim.sd_arcsec && r.sd_arcsec > *lim.sd_arcsec) {
    add(fmt::format("{} residual sd {:.3f} arcsec > {} arcsec", axis, r.sd_arcsec, *lim.sd_arcsec));
  }
  if (lim.max_abs_arcsec && r.max_abs_arcsec > *lim.max_abs_arcsec) {
    add(fmt::format("{} max |residual| {:.3f} arcsec > {} arcsec", axis, r.max_abs_arcsec, *lim.max_abs_arcsec));
  }
  if (lim.min_points && static_cast<int64_t>(r.points) < *lim.min_points) {
    add(fmt::format("{} {} points < {}", axis, r.points, *lim.min_points));
  }
  return broken;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The session

SessionResult run_session(const SessionRequest& req) {
  const auto t_start = std::chrono::steady_clock::now();
  SessionResult res;
  const bool resuming = !req.resume_dir.empty();

  // From here on SIGINT/SIGTERM ask for a clean stop rather than killing the process, so a run
  // folder once made always says how its run ended.
  RunControl own;
  RunControl& control = req.control ? *req.control : own;
  std::optional<SignalScope> signals;
  if (!req.control) signals.emplace(control);

  Diagnostics d(req.procedure.origin);
  const Plan plan = expand(req.procedure, req.stand.bench, d);
  d.throw_if_any();
  res.points_total = static_cast<int64_t>(plan.points);

  // Console logging first; the run folder's events.log joins once the folder exists.
  auto console = std::make_shared<spdlog::sinks::stderr_sink_mt>();
  console->set_level(req.quiet ? spdlog::level::off : req.tty ? spdlog::level::warn : spdlog::level::info);
  console->set_pattern("fpss-stand run: %v");
  auto log = std::make_shared<spdlog::logger>("run", spdlog::sinks_init_list{console});
  log->set_level(spdlog::level::debug);
  log->flush_on(spdlog::level::info);

  RunInfo prior;
  if (resuming) {
    prior = read_run_info(req.resume_dir);
    const std::string outcome = prior.doc.value("outcome", "");
    if (outcome == "completed") {
      throw InputError(fmt::format("{}: the run is already completed; nothing to resume", req.resume_dir.string()));
    }
  }

  // The bench.
  std::unique_ptr<EmulatorProcess> emu;
  StandConfig stand = req.stand;
  fs::path emu_log_tmp;
  if (req.emulator) {
    EmulatorLaunch l;
    l.exe = req.emulator->exe;
    l.args = req.emulator->args(!resuming);
    if (resuming) {
      l.log = req.resume_dir / "emulator.log";
    } else {
      fs::create_directories(req.runs_dir);
      emu_log_tmp = req.runs_dir / fmt::format(".emulator-{}.log", ::getpid());
      l.log = emu_log_tmp;
    }
    emu = std::make_unique<EmulatorProcess>(l);
    log->info("starting the emulated bench: {}", fmt::join(emu->command(), " "));
    emu->start();
    stand.gimbal.endpoint = emu->gimbal_endpoint();
    stand.sensor.endpoint = emu->sensor_endpoint();
    log->info("emulated bench ready: gimbal {}, sensor {}", stand.gimbal.endpoint, stand.sensor.endpoint);
  }
  auto cleanup_tmp_log = [&] {
    if (!emu_log_tmp.empty() && fs::exists(emu_log_tmp)) {
      std::error_code ec;
      if (!res.run_dir.empty()) fs::rename(emu_log_tmp, res.run_dir / "emulator.log", ec);
      if (res.run_dir.empty() || ec) fs::remove(emu_log_tmp, ec);
    }
  };

  std::unique_ptr<Gimbal> gimbal;
  std::unique_ptr<Sensor> sensor;
  std::string id_reply, unit;
  try {
    stand.gimbal.limits = stand.bench.limits;
    gimbal = make_gimbal(stand.gimbal);
    sensor = make_sensor(stand.sensor);
    gimbal->connect();
    sensor->connect();
    id_reply = sensor->identify();
    unit = serial_from_id(id_reply);
    log->info("sensor: {}", id_reply);
  } catch (...) {
    if (emu) emu->stop();
    cleanup_tmp_log();
    throw;
  }
  if (!stand.unit_serial.empty() && unit != stand.unit_serial) {
    if (emu) emu->stop();
    cleanup_tmp_log();
    throw InputError(fmt::format("{}: the sensor reports serial \"{}\" ({}), the stand file expects \"{}\"",
                                 stand.origin.empty() ? "stand" : stand.origin, unit, id_reply, stand.unit_serial));
  }
  if (resuming && prior.doc.value("unit", unit) != unit) {
    if (emu) emu->stop();
    throw InputError(fmt::format("{}: the run was made on unit \"{}\", the sensor now reports \"{}\"",
                                 req.resume_dir.string(), prior.doc.value("unit", ""), unit));
  }

  // The run folder.
  const std::string now_utc = utc_now_iso();
  nlohmann::json doc;
  int session = 1;
  if (resuming) {
    res.run_dir = req.resume_dir;
    doc = prior.doc;
    session = static_cast<int>(doc.value("sessions", nlohmann::json::array()).size()) + 1;
  } else {
    res.run_dir = make_run_dir(req.runs_dir, now_utc, unit, req.procedure.name);
    cleanup_tmp_log();
  }
  const std::string run_id = res.run_dir.filename().string();
  auto file_sink = std::make_shared<spdlog::sinks::basic_file_sink_mt>((res.run_dir / "events.log").string());
  file_sink->set_pattern("%Y-%m-%dT%H:%M:%S.%e [%l] %v");
  log->sinks().push_back(file_sink);
  log->info("run {} session {}: procedure {} ({}), unit {}, {}", run_id, session, req.procedure.name,
            req.procedure.origin, unit, req.emulator ? "emulated bench" : "stand " + stand.stand_id);

  // The drivers log through spdlog's default logger: their retries belong in events.log too.
  struct DefaultLogger {
    std::shared_ptr<spdlog::logger> prev = spdlog::default_logger();
    explicit DefaultLogger(std::shared_ptr<spdlog::logger> l) { spdlog::set_default_logger(std::move(l)); }
    ~DefaultLogger() { spdlog::set_default_logger(prev); }
  } default_logger(log);

  RunRecorder rec(res.run_dir);
  if (rec.cut_bytes() > 0) {
    log->warn("samples.csv: cut {} bytes of a point that never completed (it is measured again)", rec.cut_bytes());
  }

  if (!resuming) {
    doc = nlohmann::json::object();
    doc["format"] = "fpss-stand run/1";
    doc["run_id"] = run_id;
    doc["software"] = {{"name", "fpss-stand"}, {"version", FPSS_VERSION}};
    doc["procedure"] = {{"name", req.procedure.name},
                        {"file", req.procedure.origin},
                        {"sha256", sha256_hex(req.procedure.text)},
                        {"text", req.procedure.text}};
    doc["stand"] = {{"file", stand.origin.empty() ? nlohmann::json() : nlohmann::json(stand.origin)},
                    {"text", stand.text.empty() ? nlohmann::json() : nlohmann::json(stand.text)},
                    {"settings", to_json(stand)}};
    doc["unit"] = unit;
    doc["sensor_id"] = id_reply;
    doc["emulated"] = req.emulator.has_value();
    if (req.emulator) doc["emulator"] = req.emulator->to_json();
    doc["started_utc"] = now_utc;
    doc["points"] = {{"total", plan.points}, {"completed", 0}};
    doc["sessions"] = nlohmann::json::array();
    doc["files"] = {{"samples", "samples.csv"}, {"journal", "points.jsonl"}, {"events", "events.log"}};
  }
  doc["outcome"] = "running";
  doc.erase("ended_utc");
  doc.erase("reason");
  nlohmann::json sess{{"session", session}, {"started_utc", now_utc}, {"first_point", rec.next_point()},
                      {"pid", ::getpid()}};
  if (emu) sess["emulator"] = {{"command", emu->command()}, {"gimbal", stand.gimbal.endpoint},
                               {"sensor", stand.sensor.endpoint}};
  doc["sessions"].push_back(sess);
  write_json_atomic(res.run_dir / "run.json", doc);

  // The catalogue: a failure there is logged, never allowed to lose the run.
  const fs::path cat_path = !req.catalogue.empty() ? req.catalogue
                            : resuming            ? res.run_dir.parent_path() / "stand.db"
                                                  : Catalogue::default_path(req.runs_dir);
  auto with_catalogue = [&](const char* what, auto&& f) {
    try {
      Catalogue cat(cat_path);
      f(cat);
    } catch (const std::exception& e) {
      log->warn("catalogue {}: {}: {}", cat_path.string(), what, e.what());
    }
  };
  with_catalogue("run start", [&](Catalogue& cat) {
    RunStart rs;
    rs.run_id = run_id;
    rs.unit = unit;
    rs.procedure = req.procedure.name;
    rs.procedure_hash = doc["procedure"]["sha256"].get<std::string>();
    rs.started_utc = doc["started_utc"].get<std::string>();
    rs.run_dir = fs::absolute(res.run_dir);
    rs.emulated = req.emulator.has_value();
    rs.stand = req.emulator ? "" : (stand.stand_id.empty() ? stand.origin : stand.stand_id);
    cat.record_run_start(rs);
  });

  // Live residual: the streaming estimator fed with every dwell, old (a resume) and new.
  std::unique_ptr<StreamingCalibrator> live;
  try {
    live = std::make_unique<StreamingCalibrator>(CalibrationOptions{}, "live");
    if (rec.has_rows()) {
      const SampleTable old = read_samples_csv(rec.samples_path());
      for (size_t i = 0; i < old.size(); ++i) live->add_sample(old.row(i));
    }
  } catch (const std::exception& e) {
    log->warn("live residual off: {}", e.what());
    live.reset();
  }
  std::string live_text;
  auto last_estimate = std::chrono::steady_clock::now() - std::chrono::seconds(10);

  Progress progress(plan.points, static_cast<size_t>(rec.next_point()), req.tty, *log);
  std::optional<CalibrationReport> last_cal;
  int calibrations = 0;

  EngineHooks hooks;
  hooks.point_done = [&](const Action&, const std::vector<RecordedRow>& rows) {
    if (live) {
      try {
        for (const auto& r : rows) live->add_sample(r.sample);
        // The estimate costs a few thousand small solves: refresh it twice a second at most.
        const bool last = progress.done() + 1 >= plan.points;
        if (last || std::chrono::steady_clock::now() - last_estimate > std::chrono::milliseconds(500)) {
          last_estimate = std::chrono::steady_clock::now();
          const auto est = live->current();
          if (est.valid) {
            live_text = fmt::format("live residual rms pitch {:.2f} yaw {:.2f} arcsec ({} pairs)", est.rms_pitch_arcsec,
                                    est.rms_yaw_arcsec, est.pairs);
          }
        }
      } catch (const std::exception& e) {
        log->warn("live residual off: {}", e.what());
        live.reset();
      }
    }
    progress.point_done(live_text);
  };
  hooks.calibrate = [&](const Action& a) {
    progress.clear();
    int64_t points_before = 0;
    for (const auto& x : plan.actions) {
      if (&x == &a) break;
      if (x.is_point()) ++points_before;
    }
    const SampleTable all = read_samples_csv(rec.samples_path());
    const SampleTable rows = rows_up_to(all, points_before);
    CalibrationOptions o;
    o.method = parse_method(a.calibrate->method).value_or(Method::differences);
    if (a.calibrate->init) o.init = load_coefficients(*a.calibrate->init);
    if (a.calibrate->max_iterations) o.max_iterations = *a.calibrate->max_iterations;
    if (a.calibrate->refine_nodes) o.refine_nodes = static_cast<size_t>(*a.calibrate->refine_nodes);
    if (a.calibrate->threads) o.threads = *a.calibrate->threads;
    o.unit = unit;
    const auto t0 = std::chrono::steady_clock::now();
    CalibrationReport rep = calibrate(rows, o);
    ++calibrations;
    const fs::path out =
        res.run_dir / (calibrations == 1 ? std::string("calibration.json") : fmt::format("calibration-{}.json", calibrations));
    save_coefficients(out, rep.coefficients());
    log->info("calibrated on {} rows of {} points in {:.2f} s -> {}\n{}", rows.size(), points_before,
              seconds_since(t0), out.filename().string(), summary_text(rep));
    res.calibration = out;
    last_cal = rep;
    with_catalogue("calibration", [&](Catalogue& cat) {
      CalibrationRecord cr = CalibrationRecord::from_calibration_json(to_json(rep.coefficients()), out.string());
      cr.unit = unit;
      cr.source = "run";
      cr.run_id = run_id;
      cr.source_ref = run_id;
      cr.date_utc = utc_now_iso();
      cat.record_calibration(cr);
    });
  };
  hooks.check = [&](const Action& a) -> std::string {
    if (!last_cal) return "no calibration to check";
    std::string broken = check_limits(a.check->pitch, last_cal->pitch.residuals, "pitch");
    const std::string y = check_limits(a.check->yaw, last_cal->yaw.residuals, "yaw");
    if (!y.empty()) broken += (broken.empty() ? "" : "; ") + y;
    log->info("check: {}", broken.empty() ? "residuals within the limits" : broken);
    return broken;
  };

  EngineResult er;
  {
    Engine engine(*gimbal, *sensor, stand.bench, plan, rec, *log, control, hooks);
    er = engine.run(session);
    res.stats = engine.stats();
  }
  progress.finish();
  try {
    sensor->disconnect();
    gimbal->disconnect();
  } catch (const std::exception& e) {
    log->warn("disconnect: {}", e.what());
  }
  if (emu) {
    const int st = emu->stop();
    log->info("emulated bench stopped (status {})", st);
  }

  res.outcome = er.outcome;
  res.reason = er.reason;
  res.points_done = er.points_done;
  const std::string end_utc = utc_now_iso();
  doc["outcome"] = to_string(er.outcome);
  if (!er.reason.empty()) doc["reason"] = er.reason;
  doc["ended_utc"] = end_utc;
  doc["points"]["completed"] = er.points_done;
  doc["safe_state"] = er.safe_state;
  auto& s = doc["sessions"].back();
  s["ended_utc"] = end_utc;
  s["outcome"] = to_string(er.outcome);
  if (!er.reason.empty()) s["reason"] = er.reason;
  s["points_completed"] = er.points_done;
  s["engine"] = {{"wall_s", res.stats.wall_s},       {"device_s", res.stats.device_s},
                 {"sleep_s", res.stats.sleep_s},     {"storage_s", res.stats.storage_s},
                 {"calibrate_s", res.stats.calibrate_s}, {"own_s", res.stats.own_s()},
                 {"points", res.stats.points},       {"remeasured", res.stats.remeasured},
                 {"recoveries", res.stats.recoveries}};
  if (sensor) {
    const SensorStats ss = sensor->stats();
    s["sensor_stats"] = {{"frames", ss.frames},       {"crc_errors", ss.crc_errors},
                         {"garbage_bytes", ss.garbage_bytes}, {"seq_gaps", ss.seq_gaps},
                         {"frames_lost", ss.frames_lost}};
  }
  if (res.calibration) doc["files"]["calibration"] = res.calibration->filename().string();
  write_json_atomic(res.run_dir / "run.json", doc);
  with_catalogue("run end", [&](Catalogue& cat) { cat.record_run_end(run_id, to_string(er.outcome), end_utc); });

  // The report needs a calibration (this session's or an earlier one's); a failure to draw it
  // never fails the run: the recording is what matters.
  if (fs::exists(res.run_dir / "calibration.json")) {
    try {
      const auto t0 = std::chrono::steady_clock::now();
      res.report = write_report(res.run_dir);
      log->info("report: {} ({:.2f} s)", res.report->string(), seconds_since(t0));
    } catch (const std::exception& e) {
      log->warn("report not written: {}", e.what());
    }
  }

  log->info("run {}: {} ({} of {} points){}", run_id, to_string(er.outcome), er.points_done, plan.points,
            er.reason.empty() ? "" : ": " + er.reason);
  res.exit_code = er.outcome == RunOutcome::completed ? 0 : 1;
  res.wall_s = seconds_since(t_start);
  log->flush();
  return res;
}

}  // namespace fpss
