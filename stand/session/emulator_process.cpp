#include "stand/session/emulator_process.h"

#include "stand/contract/emulator_contract.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <thread>

namespace fpss {

EmulatorProcess::EmulatorProcess(EmulatorLaunch launch) : launch_(std::move(launch)) {}

EmulatorProcess::~EmulatorProcess() { stop(); }

std::vector<std::string> EmulatorProcess::command() const {
  std::vector<std::string> c{launch_.exe.string(), "emulate", "--modbus-port", "0"};
  c.insert(c.end(), launch_.args.begin(), launch_.args.end());
  return c;
}

std::string EmulatorProcess::stderr_tail() const {
  if (launch_.log.empty()) return {};
  std::ifstream in(launch_.log);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (text.size() > 2000) text = "..." + text.substr(text.size() - 2000);
  while (!text.empty() && text.back() == '\n') text.pop_back();
  return text.empty() ? std::string() : "\n" + text;
}

void EmulatorProcess::start() {
  if (pid_ > 0) return;
  const std::vector<std::string> cmd = command();
  int out[2];
  if (::pipe2(out, O_CLOEXEC) != 0) throw std::runtime_error(fmt::format("emulator: pipe: {}", std::strerror(errno)));
  UniqueFd out_read(out[0]), out_write(out[1]);
  UniqueFd err_fd(::open(launch_.log.empty() ? "/dev/null" : launch_.log.c_str(),
                         O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644));
  if (!err_fd) {
    throw std::runtime_error(fmt::format("emulator: cannot open {}: {}", launch_.log.string(), std::strerror(errno)));
  }
  std::vector<char*> argv;
  for (const auto& s : cmd) argv.push_back(const_cast<char*>(s.c_str()));
  argv.push_back(nullptr);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error(fmt::format("emulator: fork: {}", std::strerror(errno)));
  if (pid == 0) {
    // Child: only async-signal-safe calls until exec.
    ::setpgid(0, 0);
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (::getppid() != parent) ::_exit(127);  // the parent died before prctl took effect
    ::dup2(out_write.get(), STDOUT_FILENO);
    ::dup2(err_fd.get(), STDERR_FILENO);
    int devnull = ::open("/dev/null", O_RDONLY);
    if (devnull >= 0) ::dup2(devnull, STDIN_FILENO);
    // Signals the stand ignores or handles must start at their defaults in the bench.
    struct sigaction sa {};
    sa.sa_handler = SIG_DFL;
    for (int s : {SIGINT, SIGTERM, SIGUSR1, SIGPIPE}) ::sigaction(s, &sa, nullptr);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  out_write.reset();
  err_fd.reset();
  pid_ = pid;
  out_fd_ = std::move(out_read);

  std::string buf;
  EmulatorReadyLines ep;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(launch_.ready_timeout_s);
  while (!ep.ready) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      stop();
      throw std::runtime_error(fmt::format("emulator: not ready within {} s{}", launch_.ready_timeout_s, stderr_tail()));
    }
    pollfd p{out_fd_.get(), POLLIN, 0};
    const int r = ::poll(&p, 1, static_cast<int>(std::min<long>(left.count(), 200)));
    if (r < 0 && errno != EINTR) break;
    if (r <= 0) continue;
    char chunk[512];
    const ssize_t n = ::read(out_fd_.get(), chunk, sizeof chunk);
    if (n <= 0) {
      int status = 0;
      ::waitpid(pid_, &status, 0);
      pid_ = -1;
      out_fd_.reset();
      throw std::runtime_error(fmt::format("emulator: exited before it was ready ({}){}",
                                           WIFEXITED(status) ? fmt::format("exit code {}", WEXITSTATUS(status))
                                                             : fmt::format("signal {}", WTERMSIG(status)),
                                           stderr_tail()));
    }
    buf.append(chunk, static_cast<size_t>(n));
    size_t nl;
    while ((nl = buf.find('\n')) != std::string::npos) {
      const std::string line = buf.substr(0, nl);
      buf.erase(0, nl + 1);
      ep.take_line(line);
    }
  }
  gimbal_ = ep.gimbal;
  sensor_ = ep.sensor;
  sensors_ = ep.sensors;
  if (gimbal_.empty() || sensor_.empty()) {
    stop();
    throw std::runtime_error(fmt::format("emulator: ready without both endpoints (gimbal \"{}\", sensor \"{}\")",
                                         gimbal_, sensor_));
  }
}

int EmulatorProcess::stop(double grace_s) {
  if (pid_ <= 0) return -1;
  ::kill(pid_, SIGTERM);
  int status = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(grace_s);
  for (;;) {
    const pid_t r = ::waitpid(pid_, &status, WNOHANG);
    if (r == pid_ || (r < 0 && errno != EINTR)) break;
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, &status, 0);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  pid_ = -1;
  out_fd_.reset();
  return status;
}

}  // namespace fpss
