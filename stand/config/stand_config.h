// Stand files (YAML): endpoints, unit serial, soft limits, timeouts, retries, axis mapping and sample rate of a bench.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "drivers/options.h"
#include "procedures/settings.h"
#include "procedures/yaml_diag.h"

namespace fpss {

// One sensor unit on the stand's gimbal (a `sensors:` entry, or the single `sensor:`).
struct StandUnit {
  std::string serial;   // expected serial; "" accepts whatever the sensor reports
  SensorOptions sensor;
  AxisMapping axes;     // how it sits on the gimbal
  // Its own engine-side options when its sensors entry gives them (none: the stand's): its RATE,
  // how late its frames may be, its clock's known offset (else clock.sensor_offset_s).
  std::optional<double> sample_rate_hz{}, frame_timeout_s{}, sensor_offset_s{};
};

// A stand as a stand file describes it: the devices' options and what the engine needs.
struct StandConfig {
  std::string origin;      // file it came from ("" when built in)
  std::string text;        // the file's text, as recorded in run.json
  std::string stand_id;    // identity of the stand, free text
  std::string unit_serial; // expected sensor serial; "" accepts whatever the sensor reports
  std::string catalogue;   // catalogue URL (docs/fleet.md); "" : the command line's or the default
  bool clock_sync_given = false;  // the file chose clock.sync (an emulator then keeps that choice)
  GimbalOptions gimbal;
  SensorOptions sensor;
  EngineSettings bench;
  // Every unit, in order (`sensors:`; `sensor:` is a list of one). The first unit's serial, options
  // and axes are also unit_serial, sensor and bench.axes above, which single-unit code reads.
  std::vector<StandUnit> units;
  bool multi_unit() const { return units.size() > 1; }
  // Makes units[0] and the single-unit fields agree again after either changed.
  void sync_first_unit();
};

nlohmann::json to_json(const StandConfig& s);  // resolved settings, for run.json

// Parses and validates a stand file; every error goes to `d` with file:line:column. The result
// is usable only when d is empty.
StandConfig parse_stand(std::string_view text, const std::string& origin, Diagnostics& d);
// Reads a file; throws InputError listing every error.
StandConfig load_stand_file(const std::filesystem::path& path);

// The stand `--emulate` uses when no stand file is given: the emulator's gimbal and sensor
// (endpoints filled in once it is up), its bench clock shared by both devices, speed-up `speed`.
StandConfig emulated_stand(double speed);
// Makes a stand (from a file or not) drive an emulator: the speed-up as time scale, and the shared
// bench clock unless the file chose clock.sync itself.
void adapt_to_emulator(StandConfig& stand, double speed);
// The stand of `run` and `accept`: the stand file (InputError when it cannot be read, its errors
// into `d`), adapted to the emulator when `emulate`; without a file, emulated_stand(speed).
StandConfig stand_for_run(const std::string& stand_file, bool emulate, double speed, Diagnostics& d);

}  // namespace fpss
