// Where a command finds runs it was not pointed at: a run named by a unique prefix of its id or
// folder, or `latest`; and the runs folder (with its catalogue) when the default runs/ has none.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace fpss::cli {

// A runs folder found below the working folder because runs/ holds no catalogue: the most recently
// written of the folders holding a stand.db (scripts/demo's build/demo/runs, ...), and the others.
struct FoundRunsDir {
  std::filesystem::path dir;
  std::vector<std::filesystem::path> others;
};
// Looks (a bounded walk, three folders deep, hidden folders skipped) only when `runs_dir` is the
// default "runs" and holds no stand.db; nullopt otherwise or when there is none.
std::optional<FoundRunsDir> find_runs_dir_nearby(const std::filesystem::path& runs_dir);
// "fpss-stand: note: no catalogue at runs/stand.db; reading DIR/stand.db (the most recent of N
// found: ...); give --runs-dir to choose" on stderr.
void note_found_runs_dir(const std::filesystem::path& runs_dir, const FoundRunsDir& found);

// The folder of the run `ref` names within `runs_dir`: a folder name or run id (run.json's
// run_id), a prefix of exactly one of them, or `latest` (the run started last). nullopt when none
// matches (or no run for `latest`); InputError naming the candidates for a prefix of several.
std::optional<std::filesystem::path> find_run_in(const std::string& ref, const std::filesystem::path& runs_dir);

}  // namespace fpss::cli
