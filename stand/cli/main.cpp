// fpss-stand: one binary, sub-commands; maps errors to the exit codes of help.h's table (2 bad
// input, 1 job failed), every one written "fpss-stand: error: ..." (hints on their own lines).
#include <fmt/format.h>

#include <cstdio>
#include <exception>
#include <string>

#include "base/errors.h"
#include "stand/cli/commands.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"
#include "stand/cli/terminal.h"

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
  fpss::cli::add_compare_import(app, run);
  fpss::cli::add_serve(app, run);
  fpss::cli::add_design(app, run);
  fpss::cli::add_investigate(app, run);
  fpss::cli::add_show(app, run);
  fpss::cli::add_msa(app, run);
  // After the sub-commands: they would inherit it.
  fpss::cli::examples(&app, {"fpss-stand run procedures/discrete_grid.yaml --emulate --runs-dir runs",
                             "fpss-stand calibrate --help"});
  // CLI11 reports a mistyped sub-command as "A subcommand is required": name it instead.
  if (argc > 1 && argv[1][0] != '-') {
    const std::string name = argv[1];
    const auto known = app.get_subcommands([&](const CLI::App* s) { return s->check_name(name); });
    if (known.empty()) {
      fpss::cli::print_error(fmt::format("unknown command '{}'; see --help{}", name,
                                         fpss::cli::did_you_mean(app, {name}, false)));
      return fpss::cli::exit_code::bad_input;
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
    // An argument not taken (a mistyped option or sub-command) close to a real one: name it after
    // CLI11's message ("The following argument was not expected: --stnad; --stnad: did you mean --stand?",
    // "--data is required; --dta: did you mean --data?").
    const std::string hint = fpss::cli::did_you_mean(*fpss::cli::deepest_parsed(app), app.remaining(true));
    fpss::cli::print_error(e.what() + hint);
    std::fprintf(stderr, "Run with --help for more information.\n");
    return fpss::cli::exit_code::bad_input;
  }
  // --quiet is quiet: the libraries' own logs (Ceres's through glog, the drivers' spdlog) too.
  if (fpss::cli::quiet_given(*fpss::cli::deepest_parsed(app))) fpss::cli::quiet_library_logs();
  try {
    return run ? run() : fpss::cli::exit_code::bad_input;
  } catch (const fpss::InputError& e) {
    fpss::cli::print_error(e.what());
    // A file given to the wrong option: name the one that takes it.
    const std::string what = e.what();
    if (what.find("\nhint: ") == std::string::npos) {
      if (const std::string hint = fpss::cli::file_hint(what); !hint.empty()) std::fprintf(stderr, "%s\n", hint.c_str());
    }
    return fpss::cli::exit_code::bad_input;
  } catch (const std::exception& e) {
    fpss::cli::print_error(e.what());
    return fpss::cli::exit_code::failed;
  }
}
