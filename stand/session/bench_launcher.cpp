#include "stand/session/bench_launcher.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include "base/errors.h"

namespace fpss {

namespace fs = std::filesystem;

namespace {

// The bench's units in its order, onto the stand's: a stand without a file (or with one unit and
// no serial) takes as many units as the bench serves; a stand file listing units must list as many.
void point_stand_at(const EmulatorProcess& emu, StandConfig& stand, spdlog::logger& log) {
  stand.gimbal.endpoint = emu.gimbal_endpoint();
  const auto& sensors = emu.sensor_endpoints();
  if (stand.units.size() == 1 && stand.units.front().serial.empty()) {
    while (stand.units.size() < sensors.size()) stand.units.push_back(stand.units.front());
  }
  if (stand.units.size() != sensors.size()) {
    throw InputError(fmt::format("{}: the stand lists {} sensor unit(s), the emulated bench serves {}",
                                 stand.origin.empty() ? "stand" : stand.origin, stand.units.size(), sensors.size()));
  }
  for (size_t u = 0; u < sensors.size(); ++u) stand.units[u].sensor.endpoint = sensors[u];
  stand.sensor.endpoint = stand.units.front().sensor.endpoint;
  log.info("emulated bench ready: gimbal {}, sensor{} {}", stand.gimbal.endpoint, sensors.size() > 1 ? "s" : "",
           fmt::join(sensors, ", "));
}

}  // namespace

void BenchLauncher::start(const SessionRequest& req, bool resuming, StandConfig& stand, spdlog::logger& log) {
  if (req.running_bench && !resuming) {
    borrowed = req.running_bench;
    log.info("on the running emulated bench: {}", fmt::join(borrowed->command(), " "));
    point_stand_at(*borrowed, stand, log);
    return;
  }
  if (!req.emulator) return;
  EmulatorLaunch l;
  l.exe = req.emulator->exe;
  l.args = req.emulator->args(!resuming);
  if (resuming) {
    l.log = req.resume_dir / "emulator.log";
  } else {
    fs::create_directories(req.runs_dir);
    tmp_log = req.runs_dir / fmt::format(".emulator-{}.log", ::getpid());
    l.log = tmp_log;
  }
  emu = std::make_unique<EmulatorProcess>(l);
  log.info("starting the emulated bench: {}", fmt::join(emu->command(), " "));
  emu->start();
  point_stand_at(*emu, stand, log);
}

void BenchLauncher::settle_log(const fs::path& run_dir) {
  if (tmp_log.empty() || !fs::exists(tmp_log)) return;
  std::error_code ec;
  if (!run_dir.empty()) fs::rename(tmp_log, run_dir / "emulator.log", ec);
  if (run_dir.empty() || ec) fs::remove(tmp_log, ec);
  tmp_log.clear();
}

}  // namespace fpss
