// fpss-stand emulate: placeholder until issue 3 lands; it refuses to pretend.
#include <cstdio>

#include "stand/commands.h"

namespace fpss::cli {

void add_emulate(CLI::App& app, Runner& run) {
  auto* sub = app.add_subcommand("emulate", "(not implemented yet: issue 3)");
  sub->allow_extras();
  sub->callback([&run] {
    run = [] {
      std::fprintf(stderr, "fpss-stand emulate: not implemented yet (issue 3)\n");
      return 1;
    };
  });
}

}  // namespace fpss::cli
