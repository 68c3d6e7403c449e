// The emulator's command-line contract: the options `fpss-stand emulate` takes and the lines it
// prints when ready. cmd_emulate serves it; the session that launches an emulator child uses it.
#pragma once
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace fpss {

// The emulated bench a run starts as a child process, and what run.json records of it.
struct EmulatorSpec {
  std::filesystem::path exe = "/proc/self/exe";
  double speed = 20;
  uint64_t seed = 1;
  std::string bench_file;            // "" : the default bench
  std::vector<std::string> effects;  // NAME:key=value,...
  std::vector<std::string> faults;   // NAME:key=value,... (not repeated on a resume)
  std::string truth_file, unit_serial;

  std::vector<std::string> args(bool with_faults = true) const;  // after `emulate --modbus-port 0`
  nlohmann::json to_json() const;
  static EmulatorSpec from_json(const nlohmann::json& j, const std::string& origin);
};

// The lines `emulate` prints on standard output once it serves, in this order, then flushes:
//   gimbal: <endpoint>       the Modbus TCP endpoint (tcp:HOST:PORT)
//   gimbal-rtu: <endpoint>   only with --modbus-rtu
//   sensor: <endpoint>       the sensor's pty (pty:PATH); one line per unit, in the bench's order
//   ready
namespace emulator_ready {
inline constexpr std::string_view gimbal = "gimbal: ", gimbal_rtu = "gimbal-rtu: ", sensor = "sensor: ",
                                  ready = "ready";
}  // namespace emulator_ready

// What the ready lines said so far.
struct EmulatorReadyLines {
  std::string gimbal, gimbal_rtu, sensor;  // sensor: the first unit's
  std::vector<std::string> sensors;         // every unit's, in order
  bool ready = false;
  // Takes one line (without its newline); false for a line that is not part of the contract.
  bool take_line(std::string_view line);
};

}  // namespace fpss
