// How a command talks to the terminal: its errors, in one style.
#pragma once
#include <string>

#include <CLI/CLI.hpp>

namespace fpss::cli {

// "fpss-stand: error: MESSAGE" on stderr: every error the binary reports, whatever its exit code.
void print_error(const std::string& message);

}  // namespace fpss::cli
