// fpss-stand diagnose: placeholder until issue 5 lands; it refuses to pretend.
#include <cstdio>

#include "stand/commands.h"

namespace fpss::cli {

void add_diagnose(CLI::App& app, Runner& run) {
  auto* sub = app.add_subcommand("diagnose", "(not implemented yet: issue 5)");
  sub->allow_extras();
  sub->callback([&run] {
    run = [] {
      std::fprintf(stderr, "fpss-stand diagnose: not implemented yet (issue 5)\n");
      return 1;
    };
  });
}

}  // namespace fpss::cli
