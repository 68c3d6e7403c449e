#include "stand/cli/terminal.h"

#include <cstdio>

namespace fpss::cli {

void print_error(const std::string& message) { std::fprintf(stderr, "fpss-stand: error: %s\n", message.c_str()); }

}  // namespace fpss::cli
