// The bench of a run: an emulator child (its log kept in the run folder) or the stand's endpoints.
#pragma once
#include <filesystem>
#include <memory>

#include <spdlog/spdlog.h>

#include "stand/config/stand_config.h"
#include "stand/session/emulator_process.h"
#include "stand/session/session.h"

namespace fpss {

struct BenchLauncher {
  std::unique_ptr<EmulatorProcess> emu;       // started for this run
  const EmulatorProcess* borrowed = nullptr;  // a bench that outlives the run (SessionRequest::running_bench)
  std::filesystem::path tmp_log;              // the child's log until the run folder exists

  // The run's emulated bench, whoever started it (null on a real stand).
  const EmulatorProcess* bench() const { return emu ? emu.get() : borrowed; }
  // Starts the emulator child when the request has one (or takes the request's running bench) and
  // points the stand's endpoints at it.
  void start(const SessionRequest& req, bool resuming, StandConfig& stand, spdlog::logger& log);
  // Moves the child's log into the run folder (or removes it when there is none).
  void settle_log(const std::filesystem::path& run_dir);
  int stop() { return emu ? emu->stop() : -1; }  // a borrowed bench goes on
  ~BenchLauncher() {
    stop();
    settle_log({});
  }
};

}  // namespace fpss
