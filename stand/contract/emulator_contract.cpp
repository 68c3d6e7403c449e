#include "stand/contract/emulator_contract.h"

#include <fmt/format.h>


#include "base/errors.h"
#include "base/text_file.h"

namespace fpss {

std::vector<std::string> EmulatorSpec::args(bool with_faults) const {
  std::vector<std::string> a{"--speed", fmt::format("{}", speed), "--seed", std::to_string(seed)};
  if (!bench_file.empty()) a.insert(a.end(), {"--bench", bench_file});
  if (!truth_file.empty()) a.insert(a.end(), {"--truth", truth_file});
  if (!unit_serial.empty()) a.insert(a.end(), {"--unit-serial", unit_serial});
  for (const auto& e : effects) a.insert(a.end(), {"--effect", e});
  if (with_faults) for (const auto& f : faults) a.insert(a.end(), {"--fault", f});
  return a;
}

nlohmann::json EmulatorSpec::to_json() const {
  nlohmann::json j{{"speed", speed},   {"seed", seed},       {"bench", bench_file},
                   {"effects", effects}, {"faults", faults}, {"truth", truth_file},
                   {"unit_serial", unit_serial}};
  if (!bench_file.empty()) {
    j["bench_text"] = read_text_file(bench_file, "bench file", kMaxConfigFileBytes);
  }
  return j;
}

EmulatorSpec EmulatorSpec::from_json(const nlohmann::json& j, const std::string& origin) {
  try {
    EmulatorSpec s;
    s.speed = j.at("speed").get<double>();
    s.seed = j.at("seed").get<uint64_t>();
    s.bench_file = j.value("bench", "");
    s.effects = j.value("effects", std::vector<std::string>{});
    s.faults = j.value("faults", std::vector<std::string>{});
    s.truth_file = j.value("truth", "");
    s.unit_serial = j.value("unit_serial", "");
    return s;
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("{}: emulator: {}", origin, e.what()));
  }
}

bool EmulatorReadyLines::take_line(std::string_view line) {
  auto after = [&](std::string_view key, std::string& out) {
    if (line.substr(0, key.size()) != key) return false;
    out = std::string(line.substr(key.size()));
    return true;
  };
  if (after(emulator_ready::gimbal, gimbal) || after(emulator_ready::gimbal_rtu, gimbal_rtu)) return true;
  if (std::string s; after(emulator_ready::sensor, s)) {
    if (sensors.empty()) sensor = s;
    sensors.push_back(std::move(s));
    return true;
  }
  if (line == emulator_ready::ready) return ready = true;
  return false;
}

}  // namespace fpss
