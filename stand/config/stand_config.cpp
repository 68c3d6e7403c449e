#include "stand/config/stand_config.h"

#include <fmt/format.h>

#include <cmath>
#include <tuple>

#include "base/errors.h"
#include "base/text_file.h"
#include "drivers/endpoints.h"

namespace fpss {

namespace {

// "+alpha", "alpha", "-beta" -> axis and sign.
bool parse_signed_axis(const std::string& s, AxisMapping::SensorAxis& axis, double& sign) {
  std::string_view v = s;
  sign = 1;
  if (!v.empty() && (v.front() == '+' || v.front() == '-')) {
    sign = v.front() == '-' ? -1 : 1;
    v.remove_prefix(1);
  }
  if (v == "alpha") axis = AxisMapping::alpha;
  else if (v == "beta") axis = AxisMapping::beta;
  else return false;
  return true;
}

std::string axis_name(AxisMapping::SensorAxis axis, double sign) {
  return std::string(sign < 0 ? "-" : "+") + (axis == AxisMapping::alpha ? "alpha" : "beta");
}

void read_endpoint(MapReader& r, std::string& out, bool gimbal) {
  auto e = r.string("endpoint", true);
  if (!e) return;
  const std::string expected = gimbal ? "modbus-tcp:HOST:PORT or modbus-rtu:DEVICE[:BAUD[:FRAMING]]"
                                      : "serial:DEVICE[:BAUD], pty:PATH or tcp:HOST:PORT";
  try {
    const Endpoint ep = parse_endpoint(*e);
    const bool modbus = ep.kind == Endpoint::Kind::modbus_tcp || ep.kind == Endpoint::Kind::modbus_rtu;
    if (modbus != gimbal) {
      r.diagnostics().error(r.node("endpoint"), fmt::format("{}: field endpoint: \"{}\" is a {} endpoint; expected {}",
                                                            r.where(), *e, to_string(ep.kind), expected));
      return;
    }
  } catch (const EndpointError& ex) {
    r.diagnostics().error(r.node("endpoint"), fmt::format("{}: field endpoint: {}", r.where(), ex.what()));
    return;
  }
  out = *e;
}

void read_sensor_options(MapReader& r, SensorOptions& o, EngineSettings& b) {
  if (auto v = r.integer("sample_rate_hz", false, 1, 200)) b.sample_rate_hz = static_cast<double>(*v);
  if (auto v = r.positive("frame_timeout_s")) b.frame_timeout_s = *v;
  if (auto v = r.positive("command_timeout_s")) o.command_timeout_s = *v;
  if (auto v = r.integer("command_retries", false, 0, 100)) o.command_retries = static_cast<int>(*v);
  if (auto v = r.integer("reconnects", false, 0, 100)) o.reconnects = static_cast<int>(*v);
  if (auto v = r.range("temperature_range_c")) std::tie(o.temperature_min_c, o.temperature_max_c) = *v;
}

void read_axes(const YAML::Node& n, const std::string& where, AxisMapping& axes, Diagnostics& d) {
  MapReader r(n, where, d);
  for (auto [key, axis, sign] : {std::tuple{"pitch", &axes.pitch_axis, &axes.pitch_sign},
                                 std::tuple{"yaw", &axes.yaw_axis, &axes.yaw_sign}}) {
    if (auto s = r.string(key)) {
      if (!parse_signed_axis(*s, *axis, *sign)) {
        d.error(r.node(key), fmt::format("{}: field {}: expected alpha, beta, +alpha, -alpha, +beta or -beta, "
                                         "got \"{}\"",
                                         where, key, *s));
      }
    }
  }
  r.finish();
  if (axes.pitch_axis == axes.yaw_axis) {
    d.error(n, fmt::format("{}: pitch and yaw both map to {}; each sensor axis must be used once", where,
                           axes.pitch_axis == AxisMapping::alpha ? "alpha" : "beta"));
  }
}

constexpr size_t kMaxStandUnits = 16;

}  // namespace

void StandConfig::sync_first_unit() {
  if (units.empty()) units.push_back({});
  units.front().serial = unit_serial;
  units.front().sensor = sensor;
  units.front().axes = bench.axes;
}

// reference: the gimbal's calibration file (docs/formats.md), relative to the stand file.
static void read_reference(MapReader& top, const std::string& origin, EngineSettings& b, Diagnostics& d) {
  const auto s = top.string("reference");
  if (!s) return;
  std::filesystem::path p = *s;
  if (p.is_relative() && !origin.empty()) p = std::filesystem::path(origin).parent_path() / p;
  try {
    b.reference = load_reference_calibration(p);
  } catch (const InputError& e) {
    d.error(top.node("reference"), fmt::format("reference: {}", e.what()));
  }
}

// sensor: one unit, or sensors: a list of units (each with its serial, endpoint and axes); the
// first unit's are also the single-unit fields.
static void read_units(MapReader& top, const YAML::Node& root, StandConfig& c, Diagnostics& d) {
  EngineSettings& b = c.bench;
  const bool listed = top.has("sensors");
  if (listed && top.has("sensor")) {
    d.error(top.node("sensors"), "stand file: give sensor (one unit) or sensors (a list), not both");
  }
  if (!listed) {
    YAML::Node n = top.node("sensor");
    if (!n.IsDefined()) d.error(root, "stand file: missing field sensor (with its endpoint), or sensors (a list of units)");
    MapReader r(n, "sensor", d);
    if (n.IsDefined()) read_endpoint(r, c.sensor.endpoint, false);  // else one error says it, not two
    read_sensor_options(r, c.sensor, b);
    if (auto v = r.string("serial")) c.unit_serial = *v;
    r.finish();
    read_axes(top.node("axes"), "axes", b.axes, d);
    c.units = {StandUnit{.serial = c.unit_serial, .sensor = c.sensor, .axes = b.axes}};
  } else {
    if (top.has("axes")) d.error(top.node("axes"), "stand file: with sensors, each unit gives its own axes");
    if (top.has("unit")) d.error(top.node("unit"), "stand file: with sensors, each unit gives its own serial (unit)");
    YAML::Node list = top.node("sensors");
    if (!list.IsSequence() || list.size() == 0 || list.size() > kMaxStandUnits) {
      d.error(list, fmt::format("sensors: expected a list of 1 to {} units, each with unit, endpoint and axes", kMaxStandUnits));
    } else {
      const EngineSettings common = b;
      for (size_t i = 0; i < list.size(); ++i) {
        const std::string where = fmt::format("sensors[{}]", i + 1);
        MapReader r(list[i], where, d);
        StandUnit u;
        read_endpoint(r, u.sensor.endpoint, false);
        if (auto v = r.string("unit", true)) u.serial = *v;
        EngineSettings mine = common;
        read_sensor_options(r, u.sensor, mine);
        // Its own rate and timeout; the first unit's pace the dwells (the engine's).
        if (list[i]["sample_rate_hz"]) u.sample_rate_hz = mine.sample_rate_hz;
        if (list[i]["frame_timeout_s"]) u.frame_timeout_s = mine.frame_timeout_s;
        if (i == 0) {
          b.sample_rate_hz = mine.sample_rate_hz;
          b.frame_timeout_s = mine.frame_timeout_s;
        }
        if (auto v = r.number("sensor_offset_s")) u.sensor_offset_s = *v;
        read_axes(r.node("axes"), where + ".axes", u.axes, d);
        r.finish();
        for (const StandUnit& o : c.units) {
          if (o.serial == u.serial && !u.serial.empty()) {
            d.error(list[i]["unit"], fmt::format("{}: unit {} is listed twice", where, u.serial));
          }
          if (o.sensor.endpoint == u.sensor.endpoint && !u.sensor.endpoint.empty()) {
            d.error(list[i]["endpoint"], fmt::format("{}: endpoint {} is another unit's", where, u.sensor.endpoint));
          }
        }
        c.units.push_back(std::move(u));
      }
      if (!c.units.empty()) {
        c.unit_serial = c.units.front().serial;
        c.sensor = c.units.front().sensor;
        b.axes = c.units.front().axes;
      }
    }
  }
}

StandConfig parse_stand(std::string_view text, const std::string& origin, Diagnostics& d) {
  StandConfig c;
  c.origin = origin;
  c.text = std::string(text);
  YAML::Node root = parse_yaml_map(text, d, "stand file: expected a map with gimbal, sensor, soft_limits, axes, ...");
  if (!d.empty()) return c;
  EngineSettings& b = c.bench;
  MapReader top(root, "stand file", d);
  if (auto s = top.string("stand")) c.stand_id = *s;
  if (auto s = top.string("unit")) c.unit_serial = *s;
  if (auto s = top.string("catalogue")) c.catalogue = *s;

  // gimbal
  {
    YAML::Node n = top.node("gimbal");
    if (!n.IsDefined()) d.error(root, "stand file: missing field gimbal (with its endpoint)");
    MapReader r(n, "gimbal", d);
    if (n.IsDefined()) read_endpoint(r, c.gimbal.endpoint, true);  // else one error says it, not two
    if (auto v = r.integer("unit_id", false, 0, 247)) c.gimbal.unit_id = static_cast<int>(*v);
    if (auto v = r.positive("response_timeout_s")) c.gimbal.response_timeout_s = *v;
    if (auto v = r.integer("retries", false, 0, 100)) c.gimbal.retries = static_cast<int>(*v);
    if (auto v = r.rate_arcsec_s("profile_rate")) b.profile_rate_arcsec_s = *v;
    if (auto v = r.positive("acceleration_arcsec_s2")) b.acceleration_arcsec_s2 = *v;
    if (auto v = r.positive("in_position_tolerance_arcsec")) b.in_position_tolerance_arcsec = *v;
    if (auto v = r.positive("move_timeout_s")) b.move_timeout_s = *v;
    if (auto v = r.positive("home_timeout_s")) b.home_timeout_s = *v;
    if (auto v = r.non_negative("watchdog_s")) b.watchdog_s = *v;
    if (auto v = r.boolean("timed_moves")) c.gimbal.timed_moves = b.timed_moves = *v;
    r.finish();
  }
  read_units(top, root, c, d);
  // soft limits
  {
    YAML::Node n = top.node("soft_limits");
    MapReader r(n, "soft_limits", d);
    if (auto v = r.angle_range_arcsec("pitch")) {
      b.limits.pitch_min_arcsec = v->first;
      b.limits.pitch_max_arcsec = v->second;
    }
    if (auto v = r.angle_range_arcsec("yaw")) {
      b.limits.yaw_min_arcsec = v->first;
      b.limits.yaw_max_arcsec = v->second;
    }
    if (auto v = r.rate_arcsec_s("max_rate")) b.limits.max_rate_arcsec_s = *v;
    r.finish();
    for (auto [lo, hi, name] : {std::tuple{b.limits.pitch_min_arcsec, b.limits.pitch_max_arcsec, "pitch"},
                                std::tuple{b.limits.yaw_min_arcsec, b.limits.yaw_max_arcsec, "yaw"}}) {
      if (!(lo <= 0 && hi >= 0)) {
        d.error(n, fmt::format("soft_limits: {} range [{}, {}] arcsec must contain the null (0)", name, lo, hi));
      }
    }
    c.gimbal.limits = b.limits;
  }
  if (b.profile_rate_arcsec_s > b.limits.max_rate_arcsec_s) {
    d.error(top.node("gimbal"), fmt::format("gimbal: profile rate {} arcsec/s is above soft_limits max rate {} arcsec/s",
                                            b.profile_rate_arcsec_s, b.limits.max_rate_arcsec_s));
  }
  // clock
  {
    MapReader r(top.node("clock"), "clock", d);
    if (auto s = r.choice("sync", {"host", "shared"})) {
      b.clock = *s == "shared" ? ClockSync::shared : ClockSync::host;
      c.clock_sync_given = true;
    }
    if (auto v = r.number("sensor_offset_s")) b.sensor_time_offset_s = *v;
    if (auto v = r.positive("time_scale")) b.time_scale = *v;
    if (auto v = r.positive("max_reference_gap_s")) b.max_reference_gap_s = *v;
    r.finish();
  }
  // points
  {
    MapReader r(top.node("points"), "points", d);
    if (auto v = r.integer("max_remeasure", false, 0, 100)) b.max_remeasure = static_cast<int>(*v);
    r.finish();
  }
  read_reference(top, origin, b, d);
  top.finish();
  return c;
}

StandConfig load_stand_file(const std::filesystem::path& path) {
  return load_yaml_file(path, "stand file", parse_stand);
}

StandConfig stand_for_run(const std::string& stand_file, bool emulate, double speed, Diagnostics& d) {
  if (stand_file.empty()) return emulated_stand(speed);
  StandConfig c = parse_stand(read_text_file(stand_file, "stand file", kMaxConfigFileBytes), stand_file, d);
  if (emulate) adapt_to_emulator(c, speed);
  return c;
}

void adapt_to_emulator(StandConfig& c, double speed) {
  // The emulator's devices both report the bench clock; a stand file may still ask for the host
  // alignment (to exercise it against the emulator).
  if (!c.clock_sync_given) c.bench.clock = ClockSync::shared;
  c.bench.time_scale = speed;
  // A Modbus request to the emulator on loopback, or a command on its pty, measured with the
  // drivers on a 2-core machine (docs/procedures.md, "Speed"): at 1000x it is 30 ms of bench time.
  c.bench.link_round_trip_s = 30e-6;
  // The emulated gimbal starts moves at a set time (a bench file may say it cannot: the scheduled
  // moves are then refused, and the engine commands each move when its dwell ends).
  c.gimbal.timed_moves = c.bench.timed_moves = true;
}

StandConfig emulated_stand(double speed) {
  StandConfig c;
  c.stand_id = "emulator";
  c.bench.profile_rate_arcsec_s = 1800;   // the emulated gimbal's defaults (fixtures/bench.h)
  c.bench.acceleration_arcsec_s2 = 3600;
  c.bench.in_position_tolerance_arcsec = 1.0;
  c.bench.sample_rate_hz = 50;
  c.gimbal.limits = c.bench.limits;
  c.sync_first_unit();
  adapt_to_emulator(c, speed);
  return c;
}

nlohmann::json to_json(const StandConfig& s) {
  return {
      {"origin", s.origin},
      {"stand", s.stand_id},
      {"unit", s.unit_serial},
      {"gimbal",
       {{"endpoint", s.gimbal.endpoint},
        {"unit_id", s.gimbal.unit_id},
        {"response_timeout_s", s.gimbal.response_timeout_s},
        {"retries", s.gimbal.retries},
        {"timed_moves", s.gimbal.timed_moves}}},
      {"sensor",
       {{"endpoint", s.sensor.endpoint},
        {"command_timeout_s", s.sensor.command_timeout_s},
        {"command_retries", s.sensor.command_retries},
        {"reconnects", s.sensor.reconnects},
        {"temperature_range_c", {s.sensor.temperature_min_c, s.sensor.temperature_max_c}}}},
      {"bench", to_json(s.bench)},
      {"units", [&] {
         nlohmann::json a = nlohmann::json::array();
         for (const StandUnit& u : s.units) {
           a.push_back({{"unit", u.serial},
                        {"endpoint", u.sensor.endpoint},
                        {"axes", {{"pitch", axis_name(u.axes.pitch_axis, u.axes.pitch_sign)},
                                  {"yaw", axis_name(u.axes.yaw_axis, u.axes.yaw_sign)}}}});
         }
         return a;
       }()},
  };
}

}  // namespace fpss
