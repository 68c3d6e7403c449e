// Help that teaches: every sub-command's --help ends with working examples, and a mistyped option or
// sub-command is answered with the closest real one.
#pragma once
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace fpss::cli {

// The process exit codes of every command: the one table, which every --help prints and main,
// accept and the Runner's result use by name.
namespace exit_code {
inline constexpr int ok = 0, failed = 1, bad_input = 2, acceptance_failed = 3, acceptance_conditional = 4;
}  // namespace exit_code
struct ExitCodeMeaning {
  int code;
  const char* meaning;
};
const std::vector<ExitCodeMeaning>& exit_code_table();
// "Exit codes:" and one line per code ("  0  ok"), as --help prints it.
std::string exit_codes_text();

// Ends `sub`'s --help with the exit codes, then "Examples:" and one command line a line (each
// "fpss-stand ..."), run from the repository root; tests/stand/help_test.cpp runs those that need no
// run folder or server.
void examples(CLI::App* sub, const std::vector<std::string>& lines);

// The closest of `candidates` to `typed` (optimal string alignment distance, a swap of two
// neighbours counting one; or `typed` the start of exactly one candidate), "" when none is close.
std::string closest(const std::string& typed, const std::vector<std::string>& candidates);

// The sub-command a parse error happened in: the deepest one parsed (the app itself when none).
const CLI::App* deepest_parsed(const CLI::App& app);

// For the arguments CLI11 did not expect in `at` (an option or sub-command name mistyped):
// "; --stnad: did you mean --stand?" for the first one close to a real option or sub-command of `at`
// (without "--stnad: " when the message names it already), else "".
std::string did_you_mean(const CLI::App& at, const std::vector<std::string>& unexpected, bool name_typed = true);

}  // namespace fpss::cli
