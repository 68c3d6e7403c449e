// fpss-stand: one binary, sub-commands; maps errors to exit codes (2 bad input, 1 job failed).
#include <fmt/format.h>

#include <cstdio>
#include <exception>
#include <string>

#include "base/errors.h"
#include "stand/cli/commands.h"

int main(int argc, char** argv) {
  CLI::App app{"fpss-stand: test-stand controller for fine pointing sun sensors"};
  app.set_version_flag("--version", FPSS_VERSION);
  app.require_subcommand(1);
  fpss::cli::Runner run;
  fpss::cli::add_angles(app, run);
  fpss::cli::add_calibrate(app, run);
  fpss::cli::add_simulate(app, run);
  fpss::cli::add_emulate(app, run);
  fpss::cli::add_run(app, run);
  fpss::cli::add_catalogue(app, run);
  fpss::cli::add_diagnose(app, run);
  fpss::cli::add_accept(app, run);
  fpss::cli::add_serve(app, run);
  fpss::cli::add_design(app, run);
  fpss::cli::add_show(app, run);
  // CLI11 reports a mistyped sub-command as "A subcommand is required": name it instead.
  if (argc > 1 && argv[1][0] != '-') {
    const std::string name = argv[1];
    const auto known = app.get_subcommands([&](const CLI::App* s) { return s->check_name(name); });
    if (known.empty()) {
      std::fprintf(stderr, "fpss-stand: unknown command '%s'; see --help\n", name.c_str());
      return 2;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  }
  try {
    return run ? run() : 2;
  } catch (const fpss::InputError& e) {
    std::fprintf(stderr, "fpss-stand: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fpss-stand: failed: %s\n", e.what());
    return 1;
  }
}
