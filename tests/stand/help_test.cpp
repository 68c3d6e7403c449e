// Help that teaches: every sub-command's --help ends with "Examples:", and the examples that need no
// run folder, server or database are run as printed (so the help cannot rot); a mistyped option or
// sub-command names the real one; a file given to the wrong option names the option that takes it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "tests/procedures/run_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using test::CommandResult;
using testing::HasSubstr;

// The names listed under "SUBCOMMANDS:" in a --help text.
std::vector<std::string> subcommands_in(const std::string& help) {
  std::vector<std::string> names;
  std::istringstream in(help);
  std::string line;
  bool in_list = false;
  while (std::getline(in, line)) {
    if (line.rfind("SUBCOMMANDS:", 0) == 0 || line.rfind("Subcommands:", 0) == 0) {
      in_list = true;
    } else if (in_list && line.rfind("  ", 0) == 0 && line.size() > 2 && line[2] != ' ') {
      names.push_back(line.substr(2, line.find(' ', 2) - 2));
    } else if (in_list && !line.empty() && line[0] != ' ') {
      in_list = false;
    }
  }
  return names;
}

// The command lines under the help's last "Examples:" heading; empty when the help does not end with it.
std::vector<std::string> examples_in(const std::string& help) {
  const auto at = help.rfind("\nExamples:\n");
  if (at == std::string::npos) return {};
  std::vector<std::string> lines;
  std::istringstream in(help.substr(at + 11));
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    if (line.rfind("  fpss-stand ", 0) != 0) return {};  // something after the examples
    lines.push_back(line.substr(2));
  }
  return lines;
}

// Every sub-command path: {"run"}, {"catalogue"}, {"catalogue", "rebuild"}, ...
std::vector<std::vector<std::string>> all_commands(const fs::path& dir) {
  std::vector<std::vector<std::string>> out, todo{{}};
  while (!todo.empty()) {
    const auto path = todo.back();
    todo.pop_back();
    auto args = path;
    args.push_back("--help");
    const CommandResult r = test::run_stand(args, dir, "list");
    EXPECT_EQ(r.code, 0) << r.err;
    for (const auto& name : subcommands_in(r.out)) {
      auto sub = path;
      sub.push_back(name);
      out.push_back(sub);
      todo.push_back(sub);
    }
  }
  return out;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& w : v) s += (s.empty() ? "" : " ") + w;
  return s;
}

// What an example needs that this test does not give it: a server that runs until stopped, a
// database server, much time (an acceptance, a second run of the grid, a long blind test), or a
// fleet's catalogue (msa: several units calibrated on several stands; tests/stand/catalogue_backends_test.cpp).
bool not_run_here(const std::string& example) {
  for (const char* what : {"postgresql://", "fpss-stand emulate", "fpss-stand serve", "fpss-stand accept",
                           "fpss-stand blindtest --cases 22", "fpss-stand msa --"}) {
    if (example.find(what) != std::string::npos) return true;
  }
  // Needs a run of several units: tests/stand/multi_unit_test.cpp runs it on one.
  if (example.find("fpss-stand diagnose --run") != std::string::npos) return true;
  // Needs a diagnosis (GAP.json) or a real stand: tests/stand/investigate_test.cpp designs and investigates.
  if (example.find("--discriminate GAP.json") != std::string::npos) return true;
  if (example.find("fpss-stand investigate --model MODEL.json") != std::string::npos) return true;
  // A full run of the grid takes the bench's time (the dry run is checked).
  return example.rfind("fpss-stand run ", 0) == 0 && example.find("--dry-run") == std::string::npos;
}

std::string replaced(std::string s, const std::string& what, const std::string& with) {
  for (auto at = s.find(what); at != std::string::npos; at = s.find(what, at + with.size())) s.replace(at, what.size(), with);
  return s;
}

TEST(Help, EverySubCommandsHelpEndsWithExamplesThatRun) {
  test::TempDir tmp("help");
  const auto commands = all_commands(tmp.path());
  ASSERT_GE(commands.size(), 18u);
  // One run of the grid on the emulated bench (fast clock): RUN_DIR and RUN_ID in the examples, and
  // the catalogue (runs/stand.db) that runs, history and catalogue read.
  const fs::path runs = tmp / "runs";
  const CommandResult made = test::run_stand(
      {"run", (test::source_dir() / "procedures" / "discrete_grid.yaml").string(), "--emulate", "--speed", "100",
       "--runs-dir", runs.string(), "--quiet", "--no-progress"},
      tmp.path(), "run");
  ASSERT_EQ(made.code, 0) << made.err;
  const auto dirs = test::run_dirs(runs);
  ASSERT_EQ(dirs.size(), 1u);
  const std::string run_id = dirs.front().filename().string();
  // A run folder where one of its files is wanted, and one of its files where the folder is.
  const std::string dir = dirs.front().string();
  const CommandResult data = test::run_stand({"calibrate", "--data", dir, "--out", (tmp / "c.json").string()}, tmp.path(), "hint1");
  EXPECT_EQ(data.code, 2);
  EXPECT_THAT(data.err, HasSubstr("hint: " + dir + " is a run folder; its recording is " + dir + "/samples.csv"));
  const CommandResult show = test::run_stand({"show", dir + "/samples.csv"}, tmp.path(), "hint2");
  EXPECT_EQ(show.code, 2);
  EXPECT_THAT(show.err, HasSubstr("hint: the file is in the run folder " + dir + "; give that folder"));
  int run = 0;
  for (const auto& cmd : commands) {
    SCOPED_TRACE(joined(cmd));
    auto args = cmd;
    args.push_back("--help");
    const CommandResult r = test::run_stand(args, tmp.path(), "help");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto examples = examples_in(r.out);
    ASSERT_GE(examples.size(), 1u) << r.out;
    EXPECT_LE(examples.size(), 2u) << r.out;
    // A command's examples in order, from a fresh folder that looks like the repository's root
    // (procedures/ and calib/ linked), so their outputs land in the temporary folder.
    const fs::path root = tmp / ("root-" + std::to_string(run++));
    fs::create_directories(root);
    for (const char* d : {"procedures", "calib"}) fs::create_directory_symlink(test::source_dir() / d, root / d);
    fs::copy(runs, root / "runs", fs::copy_options::recursive);
    // Examples of this command (one may first make what the other needs: simulate before calibrate).
    EXPECT_TRUE(std::any_of(examples.begin(), examples.end(),
                            [&](const std::string& ex) { return ex.find(joined(cmd)) != std::string::npos; }))
        << r.out;
    for (const auto& printed : examples) {
      if (not_run_here(printed)) continue;
      SCOPED_TRACE(printed);
      const std::string ex = replaced(replaced(printed, "RUN_DIR", "runs/" + run_id), "RUN_ID", run_id);
      const std::string line =
          "cd '" + root.string() + "' && exec '" + test::stand_binary().string() + "'" + ex.substr(10);
      const CommandResult e = test::run_command({"/bin/sh", "-c", line}, tmp.path(), "example", 60);
      EXPECT_EQ(e.code, 0) << e.out << e.err;
    }
  }
}

// The "Exit codes:" block of a --help text (up to the next blank line), "" when there is none.
std::string exit_codes_in(const std::string& help) {
  const auto at = help.find("\nExit codes:\n");
  if (at == std::string::npos) return {};
  const auto end = help.find("\n\n", at + 1);
  return help.substr(at + 1, end == std::string::npos ? std::string::npos : end - at);
}

// One table of exit codes, the same in every sub-command's --help and the binary's own.
TEST(Help, EverySubCommandsHelpShowsTheOneTableOfExitCodes) {
  test::TempDir tmp("help-exit-codes");
  const std::string table = exit_codes_in(test::run_stand({"--help"}, tmp.path(), "top").out);
  for (const char* line : {"\n  0  ok\n", "\n  1  the job failed", "\n  2  bad usage or bad input",
                           "\n  3  acceptance failed", "\n  4  acceptance conditional"}) {
    EXPECT_THAT(table, HasSubstr(line));
  }
  const auto commands = all_commands(tmp.path());
  ASSERT_GE(commands.size(), 18u);
  for (const auto& cmd : commands) {
    auto args = cmd;
    args.push_back("--help");
    const CommandResult r = test::run_stand(args, tmp.path(), "help");
    EXPECT_EQ(exit_codes_in(r.out), table) << joined(cmd) << "\n" << r.out;
  }
  // accept's own line says the same codes.
  EXPECT_THAT(test::run_stand({"--help"}, tmp.path(), "top").out, HasSubstr("(exit 0 pass, 3 fail, 4 conditional)"));
}

class Hints : public testing::Test {
 protected:
  CommandResult run(const std::vector<std::string>& args, const std::string& tag = "cli") const {
    return test::run_stand(args, dir_.path(), tag, 60);
  }
  std::string src(const std::string& rel) const { return (test::source_dir() / rel).string(); }
  std::string recording() const {
    const std::string rec = (dir_ / "rec.csv").string();
    const CommandResult r = run({"simulate", "--out", rec, "--samples-per-dwell", "2"}, "sim");
    EXPECT_EQ(r.code, 0) << r.err;
    return rec;
  }
  test::TempDir dir_{"hints"};
};

TEST_F(Hints, AMistypedOptionNamesTheClosestOne) {
  const CommandResult r = run({"run", src("procedures/discrete_grid.yaml"), "--stnad", src("procedures/example_stand.yaml"),
                               "--dry-run"});
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr("--stnad"));
  EXPECT_THAT(r.err, HasSubstr("--stnad: did you mean --stand?"));
  const CommandResult eq = run({"calibrate", "--dta=x.csv", "--out", "c.json"});
  EXPECT_EQ(eq.code, 2);
  EXPECT_THAT(eq.err, HasSubstr("--dta: did you mean --data?"));
  // Nothing close: no guess.
  const CommandResult far = run({"angles", "--frobnicate", "--model", "m.json", "--alpha", "0", "--beta", "0"});
  EXPECT_EQ(far.code, 2);
  EXPECT_THAT(far.err, HasSubstr("--frobnicate"));
  EXPECT_THAT(far.err, testing::Not(HasSubstr("did you mean")));
}

TEST_F(Hints, AMistypedSubCommandNamesTheClosestOne) {
  const CommandResult r = run({"calbrate", "--data", "x.csv"});
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr("unknown command 'calbrate'; see --help; did you mean 'calibrate'?"));
  const CommandResult nested = run({"catalogue", "rebiuld"});
  EXPECT_EQ(nested.code, 2);
  EXPECT_THAT(nested.err, HasSubstr("rebiuld: did you mean 'rebuild'?"));
  const CommandResult far = run({"frobnicate"});
  EXPECT_EQ(far.code, 2);
  EXPECT_THAT(far.err, testing::Not(HasSubstr("did you mean")));
  // A published set's name one letter off.
  const CommandResult set = run({"compare", "a-6-fpss", "a-6-fpss1"});
  EXPECT_EQ(set.code, 2);
  EXPECT_THAT(set.err, HasSubstr("did you mean a-6-fpss1?"));
}

TEST_F(Hints, ASamplesCsvGivenAsACoefficientFileNamesData) {
  const std::string rec = recording();
  const CommandResult r = run({"diagnose", "--model", rec, "--data", rec, "--out", (dir_ / "gap.json").string()});
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr("fpss-stand: error: " + rec));  // the reader's message first, as before
  EXPECT_THAT(r.err, HasSubstr("hint: " + rec + " is a samples CSV; diagnose takes it with --data"));
  const CommandResult a = run({"angles", "--model", rec, "--alpha", "0", "--beta", "0"});
  EXPECT_EQ(a.code, 2);
  EXPECT_THAT(a.err, HasSubstr("hint: " + rec + " is a samples CSV; calibrate and diagnose take it with --data"));
  const CommandResult init = run({"calibrate", "--data", rec, "--init", rec, "--out", (dir_ / "cal.json").string()});
  EXPECT_EQ(init.code, 2);
  EXPECT_THAT(init.err, HasSubstr("is a samples CSV; calibrate takes it with --data"));
}

TEST_F(Hints, ACoefficientFileGivenAsDataNamesTheOptionsThatTakeIt) {
  const std::string cal = src("calib/data/published/a-6-fpss1.json");
  const CommandResult r = run({"calibrate", "--data", cal, "--out", (dir_ / "cal.json").string()});
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr("fpss-stand: error: " + cal));
  EXPECT_THAT(r.err, HasSubstr("hint: " + cal + " is a coefficient file; calibrate takes it with --init or --truth"));
}

TEST_F(Hints, AProcedureAndAStandFileSwapped) {
  const std::string proc = src("procedures/discrete_grid.yaml"), stand = src("procedures/example_stand.yaml");
  const CommandResult r = run({"run", stand, "--stand", proc, "--dry-run"});
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, testing::AnyOf(HasSubstr("hint: " + proc + " is a procedure file; run takes it as PROCEDURE"),
                                    HasSubstr("hint: " + stand + " is a stand file; run takes it with --stand")));
}

}  // namespace
}  // namespace fpss
