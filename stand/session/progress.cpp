#include "stand/session/progress.h"

#include <fmt/format.h>

#include <cmath>

namespace fpss {

std::string clock_text(double s) {
  const auto t = static_cast<long>(std::lround(std::max(0.0, s)));
  if (t >= 3600) return fmt::format("{}:{:02}:{:02}", t / 3600, (t % 3600) / 60, t % 60);
  return fmt::format("{}:{:02}", t / 60, t % 60);
}

Progress::Progress(size_t total, size_t done, bool tty, spdlog::logger& log, FILE* out)
    : total_(total), done_(done), start_done_(done), tty_(tty), log_(log), out_(out),
      t0_(std::chrono::steady_clock::now()) {}

std::string Progress::line(const std::string& live) const {
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  const size_t here = done_ - start_done_;
  std::string eta = "--:--";
  if (here > 0 && done_ <= total_) eta = clock_text(elapsed / static_cast<double>(here) * (total_ - done_));
  const double pct = total_ ? 100.0 * static_cast<double>(done_) / static_cast<double>(total_) : 100.0;
  std::string s = fmt::format("points {}/{} ({:.0f}%)  elapsed {}  ETA {}", done_, total_, pct, clock_text(elapsed), eta);
  if (!live.empty()) s += "  " + live;
  return s;
}

void Progress::point_done(const std::string& live) {
  std::lock_guard lock(mu_);
  ++done_;
  const auto now = std::chrono::steady_clock::now();
  if (tty_) {
    // Redraw at most 20 times a second: a terminal is slower than a fast emulated bench.
    if (done_ < total_ && now - last_draw_ < std::chrono::milliseconds(50)) return;
    last_draw_ = now;
    std::fprintf(out_, "\r\033[K%s", line(live).c_str());
    std::fflush(out_);
    drawn_ = true;
  } else {
    // Not a terminal (a pipe, CI's log): one line per point would flood it; events.log keeps them.
    log_.debug("{}", line(live));
  }
}

void Progress::skipped(size_t n) {
  std::lock_guard lock(mu_);
  done_ += n;
  start_done_ += n;  // not measured here: the ETA's rate is of the points measured
}

void Progress::clear() { leave_line("\r\033[K"); }

void Progress::finish() { leave_line("\n"); }

void Progress::leave_line(const char* how) {
  std::lock_guard lock(mu_);
  if (tty_ && drawn_) {
    std::fputs(how, out_);
    std::fflush(out_);
    drawn_ = false;
  }
}

void Progress::note(const std::string& text) {
  std::lock_guard lock(mu_);
  if (!tty_) {
    log_.info("{}", text);
    return;
  }
  std::fprintf(out_, "%s%s\n", drawn_ ? "\r\033[K" : "", text.c_str());
  std::fflush(out_);
  drawn_ = false;
  last_draw_ = {};  // the next point draws the live line again at once
}

}  // namespace fpss
