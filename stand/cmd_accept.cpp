// fpss-stand accept: placeholder until issue 6 lands; it refuses to pretend.
#include <cstdio>

#include "stand/commands.h"

namespace fpss::cli {

void add_accept(CLI::App& app, Runner& run) {
  auto* sub = app.add_subcommand("accept", "(not implemented yet: issue 6)");
  sub->allow_extras();
  sub->callback([&run] {
    run = [] {
      std::fprintf(stderr, "fpss-stand accept: not implemented yet (issue 6)\n");
      return 1;
    };
  });
}

}  // namespace fpss::cli
