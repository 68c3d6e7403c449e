// fpss-stand run: placeholder until issue 4 lands; it refuses to pretend.
#include <cstdio>

#include "stand/commands.h"

namespace fpss::cli {

void add_run(CLI::App& app, Runner& run) {
  auto* sub = app.add_subcommand("run", "(not implemented yet: issue 4)");
  sub->allow_extras();
  sub->callback([&run] {
    run = [] {
      std::fprintf(stderr, "fpss-stand run: not implemented yet (issue 4)\n");
      return 1;
    };
  });
}

}  // namespace fpss::cli
