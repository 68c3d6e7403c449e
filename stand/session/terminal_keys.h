// Keys on the operator's terminal during a run: p pause, r resume, a abort to the safe state.
#pragma once
#include <termios.h>

#include <functional>
#include <string>
#include <thread>

#include "base/unique_fd.h"
#include "procedures/engine.h"

namespace fpss {

// While it lives, the terminal on `fd` is in non-canonical mode without echo (signals stay on:
// Ctrl-C still interrupts) and a thread turns keys into RunControl requests. The terminal's own
// settings come back on every way out: the destructor (normal return, exception), and the
// signals that would end or stop the process with the terminal still changed (SIGHUP, SIGQUIT,
// SIGABRT, SIGTSTP; SIGINT and SIGTERM are the session's and end in a clean return).
class TerminalKeys {
 public:
  // `say` is told what each key did (called on the key thread).
  TerminalKeys(int fd, RunControl& control, std::function<void(const std::string&)> say);
  ~TerminalKeys();
  TerminalKeys(const TerminalKeys&) = delete;
  TerminalKeys& operator=(const TerminalKeys&) = delete;

  // `fd` is a terminal and this process is its foreground job (keys make sense; a background
  // job that changed the terminal or read from it would be stopped by SIGTTOU or SIGTTIN).
  static bool foreground(int fd);
  // What a key asks for, "" for keys that mean nothing; applies it to `control`.
  static std::string apply_key(char key, RunControl& control);

 private:
  void read_keys();

  int fd_;
  RunControl& control_;
  std::function<void(const std::string&)> say_;
  UniqueFd wake_read_, wake_write_;  // a pipe: the destructor writes to it to end the thread
  std::thread thread_;
};

}  // namespace fpss
