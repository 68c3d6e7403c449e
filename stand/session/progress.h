// Progress of a run: one rewritten line on a terminal; otherwise debug log lines (events.log only,
// not the console).
#pragma once
#include <chrono>
#include <cstdio>
#include <mutex>
#include <string>

#include <spdlog/logger.h>

namespace fpss {

class Progress {
 public:
  // `done` points were completed before this session (a resume); `tty` draws the live line on `out`.
  Progress(size_t total, size_t done, bool tty, spdlog::logger& log, FILE* out = stderr);

  // A point was completed; `live` is the streaming estimator's word on it (may be empty).
  void point_done(const std::string& live);
  // Points that will not be measured (an adaptive stop) count as done.
  void skipped(size_t n);
  // Removes the live line before other output (a terminal only).
  void clear();
  void finish();
  // A line for the operator among the progress (a terminal: the live line is redrawn at the next
  // point; otherwise a log line). Safe from another thread (the keys).
  void note(const std::string& text);

  size_t done() const { return done_; }
  std::string line(const std::string& live) const;  // the text shown, for tests and logs

 private:
  // Ends the live line with `how` (a terminal with a line drawn only).
  void leave_line(const char* how);

  size_t total_, done_, start_done_;
  bool tty_;
  spdlog::logger& log_;
  FILE* out_;
  std::chrono::steady_clock::time_point t0_;
  std::chrono::steady_clock::time_point last_draw_{};
  bool drawn_ = false;
  std::mutex mu_;
};

// "1:05", "12:03:09"
std::string clock_text(double seconds);

}  // namespace fpss
