#include "stand/cli/terminal.h"

#include <glog/logging.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdio>

namespace fpss::cli {

void print_error(const std::string& message) { std::fprintf(stderr, "fpss-stand: error: %s\n", message.c_str()); }

void print_note(const std::string& message) { std::fprintf(stderr, "fpss-stand: note: %s\n", message.c_str()); }

bool draw_progress(bool forced, bool no_progress, bool quiet) {
  if (forced) return true;
  // A pipe or a file (CI, `| tee`, a log) would get one line per point: the terminal only.
  return !no_progress && !quiet && ::isatty(STDERR_FILENO) == 1;
}

void add_progress_options(CLI::App* sub, bool& forced, bool& no_progress) {
  auto* on = sub->add_flag("--progress", forced, "Draw the live progress line even when stderr is not a terminal");
  auto* off = sub->add_flag("--no-progress", no_progress, "No live progress line, even on a terminal");
  on->excludes(off);
}

bool quiet_given(const CLI::App& sub) {
  const CLI::Option* q = sub.get_option_no_throw("--quiet");
  return q != nullptr && q->count() > 0;
}

void quiet_library_logs() {
  // Ceres logs through glog to stderr; only a fatal message (which aborts anyway) gets through.
  FLAGS_minloglevel = google::GLOG_FATAL;
  FLAGS_stderrthreshold = google::GLOG_FATAL;
  spdlog::default_logger()->set_level(spdlog::level::off);
}

}  // namespace fpss::cli
