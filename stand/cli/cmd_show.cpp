// fpss-stand show RUN / report RUN: a run's summary (outcome, verdict, points, residuals, files), and its report drawn again.
#include <fmt/format.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "base/errors.h"
#include "base/json_file.h"
#include "base/text_file.h"
#include "stand/acceptance/acceptance.h"
#include "stand/catalogue/run_file.h"
#include "stand/cli/commands.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"
#include "stand/cli/run_lookup.h"
#include "stand/report/report.h"
#include "stand/report/run_summary.h"

namespace fpss::cli {
namespace {

namespace fs = std::filesystem;

struct ShowArgs {
  std::string run, runs_dir = "runs";
  bool json = false;
};

// A run named within --runs-dir (its id, folder name, a unique prefix of either, or `latest`); with
// the default runs/ holding no catalogue, within the runs folder found nearby (the demo's).
std::optional<fs::path> find_run_by_id(const ShowArgs& a) {
  if (a.run.find('/') != std::string::npos || a.run == "." || a.run == "..") return std::nullopt;
  // An id is one folder name: no separators, no "." or "..", so it cannot leave the runs folder.
  if (auto in_runs = find_run_in(a.run, a.runs_dir)) return in_runs;
  if (const auto found = find_runs_dir_nearby(a.runs_dir)) {
    if (auto there = find_run_in(a.run, found->dir)) {
      note_found_runs_dir(a.runs_dir, *found);
      return there;
    }
  }
  return std::nullopt;
}

// RUN is a run folder's path, or a run within --runs-dir (find_run_by_id).
fs::path find_run(const ShowArgs& a) {
  if (a.run.empty()) throw InputError("give RUN: a run folder or a run id within --runs-dir");
  const fs::path as_path = a.run;
  if (fs::is_directory(as_path) && fs::exists(as_path / "run.json")) return as_path;
  if (auto by_id = find_run_by_id(a)) return *by_id;
  if (fs::is_directory(as_path)) {
    // A runs folder given as RUN: its runs are listed by `runs`.
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(as_path, ec)) {
      if (e.is_directory() && fs::is_regular_file(e.path() / "run.json")) {
        throw InputError(fmt::format("{}: not a run folder (no run.json)\nhint: it holds run folders; list them with "
                                     "`fpss-stand runs --runs-dir {}`",
                                     a.run, a.run));
      }
    }
    throw InputError(fmt::format("{}: not a run folder (no run.json)", a.run));
  }
  // A file of a run folder (its samples.csv, report.html): the folder is the run.
  if (fs::is_regular_file(as_path) && as_path.has_parent_path() && fs::is_regular_file(as_path.parent_path() / "run.json")) {
    throw InputError(fmt::format("{}: no such run folder, and no run with that id in {}\nhint: the file is in the run "
                                 "folder {}; give that folder",
                                 a.run, a.runs_dir, as_path.parent_path().string()));
  }
  throw InputError(fmt::format("{}: no such run folder, and no run with that id in {}", a.run, a.runs_dir));
}

int show_command(const ShowArgs& a) {
  const RunSummary s = read_run_summary(find_run(a));
  if (a.json) {
    std::printf("%s\n", s.to_json().dump(1).c_str());
  } else {
    std::fputs(s.text().c_str(), stdout);
  }
  return 0;
}

// A re-drawn report keeps the acceptance certificate of an acceptance run.
int report_command(const ShowArgs& a) {
  const fs::path dir = find_run(a);
  ReportOptions ro;
  if (fs::exists(dir / "acceptance.json")) {
    // Checked with the limits of every JSON reader, then read again keeping the certificate's key order.
    const fs::path path = dir / "acceptance.json";
    const std::string text = read_text_file(path, "acceptance certificate", kMaxConfigFileBytes);
    parse_json_text(text, path.string());
    ro.extra_sections.push_back({"acceptance", "Acceptance", certificate_html(nlohmann::ordered_json::parse(text))});
  }
  const fs::path out = write_report(dir, ro);
  std::printf("report: %s\n", out.c_str());
  return 0;
}

void add_run_options(CLI::App* sub, ShowArgs& a) {
  expect_file(sub, sub->add_option("run", a.run, "RUN: a run folder, or a run id within --runs-dir (a unique prefix, or latest)")->required(), a.run,
              FileKind::run_folder);
  sub->add_option("--runs-dir", a.runs_dir, "Where run folders are (for a run id)")->capture_default_str();
}

}  // namespace

void add_show(CLI::App& app, Runner& run) {
  auto a = std::make_shared<ShowArgs>();
  auto* show = app.add_subcommand("show", "A run's summary: outcome, verdict, points, residuals, files");
  add_run_options(show, *a);
  show->add_flag("--json", a->json, "Print the summary as JSON");
  examples(show, {"fpss-stand show RUN_DIR", "fpss-stand show latest --runs-dir runs --json"});
  show->callback([&run, a] { run = [a] { return show_command(*a); }; });

  auto b = std::make_shared<ShowArgs>();
  auto* report = app.add_subcommand("report", "Draw a run's report.html again (after a re-calibration, ...)");
  add_run_options(report, *b);
  examples(report, {"fpss-stand report RUN_DIR", "fpss-stand report RUN_ID --runs-dir runs"});
  report->callback([&run, b] { run = [b] { return report_command(*b); }; });
}

}  // namespace fpss::cli
