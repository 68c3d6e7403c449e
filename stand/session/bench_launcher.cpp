#include "stand/session/bench_launcher.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

namespace fpss {

namespace fs = std::filesystem;

void BenchLauncher::start(const SessionRequest& req, bool resuming, StandConfig& stand, spdlog::logger& log) {
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
  stand.gimbal.endpoint = emu->gimbal_endpoint();
  stand.sensor.endpoint = emu->sensor_endpoint();
  log.info("emulated bench ready: gimbal {}, sensor {}", stand.gimbal.endpoint, stand.sensor.endpoint);
}

void BenchLauncher::settle_log(const fs::path& run_dir) {
  if (tmp_log.empty() || !fs::exists(tmp_log)) return;
  std::error_code ec;
  if (!run_dir.empty()) fs::rename(tmp_log, run_dir / "emulator.log", ec);
  if (run_dir.empty() || ec) fs::remove(tmp_log, ec);
  tmp_log.clear();
}

}  // namespace fpss
