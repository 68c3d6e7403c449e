#include "stand/cli/terminal.h"

#include <unistd.h>

#include <cstdio>

namespace fpss::cli {

void print_error(const std::string& message) { std::fprintf(stderr, "fpss-stand: error: %s\n", message.c_str()); }

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

}  // namespace fpss::cli
