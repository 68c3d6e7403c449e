#include "stand/session/session_units.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <limits>

#include "base/errors.h"
#include "calib/reduction.h"
#include "calib/unit_alignment.h"
#include "drivers/endpoints.h"
#include "stand/session/session.h"

namespace fpss {

namespace fs = std::filesystem;

namespace {

std::string stand_name(const StandConfig& stand) { return stand.origin.empty() ? "stand" : stand.origin; }

void connect_unit(SessionUnit& u, size_t index, bool several, const StandConfig& stand, spdlog::logger& log) {
  u.sensor = make_sensor(u.cfg.sensor);
  u.sensor->connect();
  u.id_reply = u.sensor->identify();
  u.serial = serial_from_id(u.id_reply);
  log.info("sensor{}: {}", several ? fmt::format(" {}", index + 1) : "", u.id_reply);
  if (!u.cfg.serial.empty() && u.serial != u.cfg.serial) {
    throw InputError(fmt::format("{}: the sensor{} reports serial \"{}\" ({}), the stand file expects \"{}\"",
                                 stand_name(stand), several ? fmt::format(" at {}", u.cfg.sensor.endpoint) : "",
                                 u.serial, u.id_reply, u.cfg.serial));
  }
}

}  // namespace

std::vector<SessionUnit> connect_units(const StandConfig& stand, spdlog::logger& log) {
  std::vector<SessionUnit> units;
  for (const StandUnit& cfg : stand.units) units.push_back(SessionUnit{cfg, nullptr, {}, {}, {}, {}, {}, {}, {}});
  const bool several = units.size() > 1;
  for (size_t i = 0; i < units.size(); ++i) {
    SessionUnit& u = units[i];
    if (!several) {
      connect_unit(u, i, several, stand, log);
      continue;
    }
    // Several units: one that cannot be reached or is not the unit expected is dropped; the others go on.
    try {
      connect_unit(u, i, several, stand, log);
    } catch (const InputError& e) {
      u.loss = UnitLoss{static_cast<int>(i), LossCause::wrong_serial, e.what(), -1};
    } catch (const DeviceError& e) {
      u.loss = UnitLoss{static_cast<int>(i), LossCause::link_failed, e.what(), -1};
    }
    if (u.serial.empty()) u.serial = !u.cfg.serial.empty() ? u.cfg.serial : fmt::format("unit{}", i + 1);
    if (u.loss) log.error("unit {} ({}) lost before the run: {}", i + 1, u.serial, u.loss->reason);
  }
  if (!several) return units;
  bool any = false;
  for (const SessionUnit& u : units) any = any || !u.loss;
  if (!any) throw InputError(fmt::format("{}: no sensor unit could be used: {}", stand_name(stand), units.front().loss->reason));
  for (size_t i = 0; i < units.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (units[i].serial == units[j].serial) {
        throw InputError(fmt::format("{}: units {} and {} both report serial \"{}\"", stand_name(stand), j + 1, i + 1,
                                     units[i].serial));
      }
    }
  }
  return units;
}

std::vector<EngineUnit> engine_units(const std::vector<SessionUnit>& units) {
  constexpr double kEngines = std::numeric_limits<double>::quiet_NaN();  // the engine's setting
  std::vector<EngineUnit> live;
  for (size_t i = 0; i < units.size(); ++i) {
    if (units[i].loss) continue;
    const StandUnit& cfg = units[i].cfg;
    live.push_back(EngineUnit{static_cast<int>(i), units[i].sensor.get(), cfg.axes, units[i].serial,
                              cfg.sample_rate_hz.value_or(kEngines), cfg.frame_timeout_s.value_or(kEngines),
                              cfg.sensor_offset_s.value_or(kEngines)});
  }
  return live;
}

std::string units_name(const std::vector<SessionUnit>& units) {
  std::vector<std::string> serials;
  for (const SessionUnit& u : units) serials.push_back(u.serial);
  return fmt::format("{}", fmt::join(serials, "+"));
}

std::vector<std::string> unit_serials(const std::vector<SessionUnit>& units) {
  std::vector<std::string> serials;
  for (const SessionUnit& u : units) serials.push_back(u.serial);
  return serials;
}

void open_recordings(std::vector<SessionUnit>& units, const RunRecorder& rec) {
  for (size_t i = 0; i < units.size(); ++i) {
    units[i].dir = rec.samples_path(i).parent_path();
    SampleTable& t = units[i].recorded;
    if (rec.has_rows()) t = read_samples_csv(rec.samples_path(i));
    // The provenance as numbers (a resume's columns stay as read: new rows are written into them).
    if (t.extra_names().empty()) {
      for (const auto& c : recorder_extra_columns()) t.add_numeric_column(c);
    }
    t.origin = rec.samples_path(i).string();
  }
}

CalibrationOptions calibration_options(const CalibrateStep& step, const SessionUnit& unit, const EngineSettings& bench) {
  CalibrationOptions o;
  o.method = parse_method(step.method).value_or(Method::differences);
  if (step.init) o.init = load_coefficients(*step.init);
  if (step.max_iterations) o.max_iterations = *step.max_iterations;
  if (step.refine_nodes) o.refine_nodes = static_cast<size_t>(*step.refine_nodes);
  if (step.threads) o.threads = *step.threads;
  o.unit = unit.serial;
  o.reference = bench.reference;
  o.mount = unit.cfg.axes;
  return o;
}

std::vector<RunFileUnit> unit_entries(const std::vector<SessionUnit>& units, const RunRecorder& rec, const fs::path& run_dir) {
  std::vector<RunFileUnit> out;
  for (size_t i = 0; i < units.size(); ++i) {
    const SessionUnit& u = units[i];
    RunFileUnit ru;
    ru.serial = u.serial;
    if (!u.id_reply.empty()) ru.sensor_id = u.id_reply;
    ru.endpoint = u.cfg.sensor.endpoint;
    ru.samples = fs::relative(rec.samples_path(i), run_dir).string();
    if (u.loss) {
      ru.outcome = "lost";
      ru.loss_cause = to_string(u.loss->cause);
      ru.reason = u.loss->reason;
      ru.lost_at_point = 0;
    }
    out.push_back(ru);
  }
  return out;
}

void record_unit_outcomes(const std::vector<SessionUnit>& units, RunOutcome outcome, const fs::path& run_dir,
                          RunFile& run) {
  for (size_t i = 0; i < units.size(); ++i) {
    RunFileUnit& ru = run.units->at(i);
    const SessionUnit& u = units[i];
    ru.outcome = u.loss ? "lost" : to_string(outcome);
    if (u.loss) {
      ru.loss_cause = to_string(u.loss->cause);
      ru.reason = u.loss->reason;
      ru.lost_at_point = u.loss->point + 1;
    }
    if (u.calibration) ru.calibration = fs::relative(*u.calibration, run_dir).string();
  }
}

void relate_units(const std::vector<SessionUnit>& units, RunFile& run, spdlog::logger& log) {
  const SessionUnit* first = nullptr;
  std::optional<UnitPose> first_pose;
  for (size_t i = 0; i < units.size(); ++i) {
    const SessionUnit& u = units[i];
    if (!u.cal || u.loss) continue;
    try {
      const ReductionOptions ro = reduction_options_of(u.cal->coefficients().extra, "calibration");
      const UnitPose pose = unit_pose(*u.cal, reduce(u.recorded, ro).dwells, u.cfg.axes);
      if (!first) {
        first = &u;
        first_pose = pose;
        continue;
      }
      const RelativePose r = relative_pose(*first_pose, pose);
      run.units->at(i).relative =
          RunFileRelative{first->serial,           r.boresight_pitch_arcsec, r.boresight_pitch_sigma_arcsec,
                          r.boresight_yaw_arcsec,  r.boresight_yaw_sigma_arcsec, r.roll_arcsec, r.roll_sigma_arcsec};
      log.info("unit {} relative to {}: boresight pitch {:+.3f} +- {:.3f}, yaw {:+.3f} +- {:.3f}, roll {:+.2f} +- {:.2f} arcsec",
               u.serial, first->serial, r.boresight_pitch_arcsec, r.boresight_pitch_sigma_arcsec, r.boresight_yaw_arcsec,
               r.boresight_yaw_sigma_arcsec, r.roll_arcsec, r.roll_sigma_arcsec);
    } catch (const DataError& e) {
      log.warn("unit {}: no relative pose: {}", u.serial, e.what());
    }
  }
}

}  // namespace fpss
