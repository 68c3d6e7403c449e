// The emulated bench as a child process: `fpss-stand emulate --modbus-port 0 ...`, its endpoints read from its ready lines.
#pragma once
#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

#include "base/unique_fd.h"

namespace fpss {

struct EmulatorLaunch {
  std::filesystem::path exe = "/proc/self/exe";  // the fpss-stand binary
  std::vector<std::string> args;                 // after `emulate --modbus-port 0`
  double ready_timeout_s = 30;
  std::filesystem::path log;  // the child's stderr goes here ("" : /dev/null)
};

// Owns the child: started by start(), ended (SIGTERM, then SIGKILL) by stop() or the destructor.
// The child lives in its own process group, so a Ctrl-C at the terminal reaches only the stand,
// which then returns the gimbal to null before stopping the bench; and it gets SIGTERM if the
// stand dies (PR_SET_PDEATHSIG), so a killed run leaves no orphan bench behind.
class EmulatorProcess {
 public:
  explicit EmulatorProcess(EmulatorLaunch launch);  // starts nothing
  ~EmulatorProcess();
  EmulatorProcess(const EmulatorProcess&) = delete;
  EmulatorProcess& operator=(const EmulatorProcess&) = delete;

  // Forks and execs, waits for "gimbal: ...", "sensor: ...", "ready". Throws std::runtime_error
  // with the child's last stderr lines when it exits or stays silent.
  void start();
  // SIGTERM and wait (up to `grace_s`, then SIGKILL). Returns the exit status as waitpid gives it,
  // -1 when nothing was running.
  int stop(double grace_s = 5.0);

  bool running() const { return pid_ > 0; }
  pid_t pid() const { return pid_; }
  const std::string& gimbal_endpoint() const { return gimbal_; }
  const std::string& sensor_endpoint() const { return sensor_; }
  const std::vector<std::string>& sensor_endpoints() const { return sensors_; }  // one per unit
  // The full command line, for run.json.
  std::vector<std::string> command() const;

 private:
  std::string stderr_tail() const;
  EmulatorLaunch launch_;
  pid_t pid_ = -1;
  UniqueFd out_fd_;
  std::string gimbal_, sensor_;
  std::vector<std::string> sensors_;
};

}  // namespace fpss
