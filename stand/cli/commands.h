// Sub-commands of the fpss-stand binary: each file cmd_<name>.cpp registers one (or a few).
#pragma once
#include <functional>

#include <CLI/CLI.hpp>

namespace fpss::cli {

// What a sub-command does once its options are parsed; returns the process exit code, one of
// exit_code_table() (help.h): 0 ok, 1 the job failed, 2 bad usage or bad input, 3 acceptance
// failed, 4 acceptance conditional.
using Runner = std::function<int()>;

// Each registers its sub-command(s) on `app`; when selected, sets `run`.
void add_angles(CLI::App& app, Runner& run);
void add_calibrate(CLI::App& app, Runner& run);
void add_simulate(CLI::App& app, Runner& run);
void add_emulate(CLI::App& app, Runner& run);
void add_run(CLI::App& app, Runner& run);        // run
void add_catalogue(CLI::App& app, Runner& run);  // runs, history, catalogue rebuild
void add_diagnose(CLI::App& app, Runner& run);  // diagnose, blindtest
void add_accept(CLI::App& app, Runner& run);    // accept
void add_compare_import(CLI::App& app, Runner& run);  // compare, import
void add_design(CLI::App& app, Runner& run);
void add_investigate(CLI::App& app, Runner& run);  // investigate (the active sim-to-real loop)
void add_show(CLI::App& app, Runner& run);      // show, report
void add_serve(CLI::App& app, Runner& run);     // serve (the web console)
void add_msa(CLI::App& app, Runner& run);       // msa (measurement-system analysis)

}  // namespace fpss::cli
