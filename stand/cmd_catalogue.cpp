// fpss-stand runs / history: placeholder until issue 4 lands; it refuses to pretend.
#include <cstdio>

#include "stand/commands.h"

namespace fpss::cli {

void add_catalogue(CLI::App& app, Runner& run) {
  for (const char* name : {"runs", "history"}) {
    auto* sub = app.add_subcommand(name, "(not implemented yet: issue 4)");
    sub->allow_extras();
    sub->callback([&run, name] {
      run = [name] {
        std::fprintf(stderr, "fpss-stand %s: not implemented yet (issue 4)\n", name);
        return 1;
      };
    });
  }
}

}  // namespace fpss::cli
