#include "stand/session/terminal_keys.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <stdexcept>

namespace fpss {

namespace {

// One terminal at a time; what the signal handlers need to put it back (async-signal-safe calls only).
int g_fd = -1;
struct termios g_saved {}, g_keys {};
constexpr int kSignals[] = {SIGHUP, SIGQUIT, SIGABRT, SIGTSTP, SIGCONT};
struct sigaction g_old[sizeof kSignals / sizeof kSignals[0]];

int slot_of(int sig) {
  for (int i = 0; i < static_cast<int>(sizeof kSignals / sizeof kSignals[0]); ++i) {
    if (kSignals[i] == sig) return i;
  }
  return -1;
}

extern "C" void on_terminal_signal(int sig);

void install(int sig) {
  struct sigaction sa {};
  sa.sa_handler = on_terminal_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  ::sigaction(sig, &sa, nullptr);
}

extern "C" void on_terminal_signal(int sig) {
  const int saved_errno = errno;
  if (g_fd < 0) return;
  if (sig == SIGCONT) {
    // Back from a stop: the next Ctrl-Z is caught again, and keys again when in the foreground
    // (`fg`; after `bg` a terminal change would stop the process with SIGTTOU).
    if (::tcgetpgrp(g_fd) == ::getpgrp()) ::tcsetattr(g_fd, TCSANOW, &g_keys);
    install(SIGTSTP);
  } else {
    ::tcsetattr(g_fd, TCSANOW, &g_saved);
    // Hand the signal on to what it did before (stop for SIGTSTP, end the process for the others):
    // it is blocked while this handler runs and is delivered when the handler returns.
    if (sig == SIGTSTP) {
      struct sigaction dfl {};
      dfl.sa_handler = SIG_DFL;
      sigemptyset(&dfl.sa_mask);
      ::sigaction(SIGTSTP, &dfl, nullptr);
    } else {
      ::sigaction(sig, &g_old[slot_of(sig)], nullptr);
    }
    ::raise(sig);
  }
  errno = saved_errno;
}

}  // namespace

std::string TerminalKeys::apply_key(char key, RunControl& control) {
  switch (key) {
    case 'p':
    case 'P':
      if (control.pause.exchange(true)) return "";
      return "pause: the gimbal holds after the point in progress (r resumes, a aborts)";
    case 'r':
    case 'R':
      if (!control.pause.exchange(false)) return "";
      return "resume";
    case 'a':
    case 'A':
      if (control.abort.exchange(true)) return "";
      return "abort: stopping and returning the gimbal to null (the safe state)";
    default: return "";
  }
}

TerminalKeys::TerminalKeys(int fd, RunControl& control, std::function<void(const std::string&)> say)
    : fd_(fd), control_(control), say_(std::move(say)) {
  if (g_fd >= 0) throw std::logic_error("TerminalKeys: one terminal at a time");
  if (::tcgetattr(fd_, &g_saved) != 0) throw std::runtime_error("TerminalKeys: not a terminal");
  int wake[2];
  if (::pipe2(wake, O_CLOEXEC) != 0) throw std::runtime_error("TerminalKeys: pipe failed");
  wake_read_.reset(wake[0]);
  wake_write_.reset(wake[1]);
  g_keys = g_saved;
  g_keys.c_lflag &= ~static_cast<tcflag_t>(ICANON | ECHO);  // ISIG stays: Ctrl-C as before
  g_keys.c_cc[VMIN] = 1;
  g_keys.c_cc[VTIME] = 0;
  g_fd = fd_;
  for (size_t i = 0; i < sizeof kSignals / sizeof kSignals[0]; ++i) {
    struct sigaction sa {};
    sa.sa_handler = on_terminal_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    ::sigaction(kSignals[i], &sa, &g_old[i]);
  }
  ::tcsetattr(fd_, TCSANOW, &g_keys);
  thread_ = std::thread([this] { read_keys(); });
}

TerminalKeys::~TerminalKeys() {
  const char c = 0;
  while (::write(wake_write_.get(), &c, 1) < 0 && errno == EINTR) {
  }
  if (thread_.joinable()) thread_.join();
  ::tcsetattr(fd_, TCSANOW, &g_saved);
  for (size_t i = 0; i < sizeof kSignals / sizeof kSignals[0]; ++i) ::sigaction(kSignals[i], &g_old[i], nullptr);
  g_fd = -1;
}

bool TerminalKeys::foreground(int fd) { return ::isatty(fd) && ::tcgetpgrp(fd) == ::getpgrp(); }

void TerminalKeys::read_keys() {
  for (;;) {
    // A job put in the background must not read (SIGTTIN would stop it): look at the terminal
    // only while in the foreground, and again every 200 ms.
    const bool fg = foreground(fd_);
    pollfd p[2] = {{fg ? fd_ : -1, POLLIN, 0}, {wake_read_.get(), POLLIN, 0}};
    if (::poll(p, 2, 200) < 0) {
      if (errno == EINTR) continue;
      return;
    }
    if (p[1].revents) return;
    if (!fg || p[0].revents == 0) continue;
    if (p[0].revents & (POLLERR | POLLHUP | POLLNVAL)) return;  // the terminal went away: Ctrl-C and signals remain
    char buf[16];
    const ssize_t n = ::read(fd_, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    for (ssize_t i = 0; i < n; ++i) {
      const std::string what = apply_key(buf[i], control_);
      if (!what.empty() && say_) say_(what);
    }
  }
}

}  // namespace fpss
