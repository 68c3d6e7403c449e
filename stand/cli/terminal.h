// How a command talks to the terminal: its errors (one style), its progress line (only on a
// terminal unless forced) and --quiet (the libraries' logs too).
#pragma once
#include <string>

#include <CLI/CLI.hpp>

namespace fpss::cli {

// "fpss-stand: error: MESSAGE" on stderr: every error the binary reports, whatever its exit code
// (a hint goes on its own line after it, "hint: ...").
void print_error(const std::string& message);
// "fpss-stand: note: MESSAGE" on stderr: what the user should know of a command that goes on.
void print_note(const std::string& message);

// Whether a run draws its live progress line: --progress forces it; else only when stderr (where
// it is drawn) is a terminal, and neither --no-progress nor --quiet is given.
bool draw_progress(bool forced, bool no_progress, bool quiet);
// Adds --progress (forced) and --no-progress to `sub`; they exclude each other.
void add_progress_options(CLI::App* sub, bool& forced, bool& no_progress);

// The parsed sub-command has a --quiet option and it was given.
bool quiet_given(const CLI::App& sub);
// Silences the libraries' own console logs for the rest of the process: glog (Ceres's solver
// warnings, "Linear solver failure ...") and spdlog's default logger (the drivers' retries).
void quiet_library_logs();

}  // namespace fpss::cli
