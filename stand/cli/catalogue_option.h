// The one `--catalogue URL` option (alias `--db`) of every sub-command that touches the catalogue, and how the URL is chosen.
#pragma once
#include <filesystem>
#include <string>

#include <CLI/CLI.hpp>

namespace fpss::cli {

// Adds `--catalogue,--db URL` to `sub`, stored in `url`.
CLI::Option* add_catalogue_option(CLI::App* sub, std::string& url);

// Adds `--catalogue-wait S` (run, accept): how long the end of a run waits for a catalogue server
// that was away before it gives up (the run folder keeps its pending mark).
CLI::Option* add_catalogue_wait_option(CLI::App* sub, double& seconds);

// The catalogue a command uses, first that is set: the command line's URL, the FPSS_CATALOGUE
// environment variable, the stand file's `catalogue:`, else "" (the command's default,
// RUNS_DIR/stand.db). A plain path is SQLite, as `sqlite:PATH` is.
std::string chosen_catalogue(const std::string& flag, const std::string& stand_value = "");

// The same with the default filled in: sqlite at RUNS_DIR/stand.db.
std::string catalogue_url(const std::string& flag, const std::filesystem::path& runs_dir,
                          const std::string& stand_value = "");

// The catalogue's URL when it names a SQLite file, "" for a server: for the output-path checks.
std::filesystem::path sqlite_file_of(const std::string& url);

}  // namespace fpss::cli
