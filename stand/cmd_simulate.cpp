// fpss-stand simulate: placeholder until issue 2 lands; it refuses to pretend.
#include <cstdio>

#include "stand/commands.h"

namespace fpss::cli {

void add_simulate(CLI::App& app, Runner& run) {
  auto* sub = app.add_subcommand("simulate", "(not implemented yet: issue 2)");
  sub->allow_extras();
  sub->callback([&run] {
    run = [] {
      std::fprintf(stderr, "fpss-stand simulate: not implemented yet (issue 2)\n");
      return 1;
    };
  });
}

}  // namespace fpss::cli
