// The command line behaving like a user's other tools: out-of-range options exit 2 before anything
// starts, one flag name per idea (old spellings kept), progress only on a terminal, one error style,
// `runs` finding the catalogue the demo made, run ids by unique prefix and `latest`, `show` naming a
// diagnosis's verdict and cause. The real binary on the emulated bench.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <regex>
#include <string>
#include <vector>

#include <glog/logging.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "stand/cli/terminal.h"
#include "tests/procedures/run_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using test::CommandResult;
using testing::HasSubstr;
using testing::Not;
using testing::StartsWith;

// A short grid and a fit (a few seconds at --speed 100).
constexpr const char* kShortGrid =
    "name: short_grid\nsteps:\n  - home\n"
    "  - null_offset_grid: {axes: [pitch, yaw], extent_deg: 0.42, step_deg: 0.06, settle_s: 0.2, frames: 3}\n"
    "  - calibrate: {method: differences}\n";

std::string src(const std::string& rel) { return (test::source_dir() / rel).string(); }

// `fpss-stand ARGS` run from `cwd` (the shell's words, quoted by the caller).
CommandResult stand_in(const fs::path& cwd, const std::string& args, const fs::path& logs, const std::string& tag) {
  return test::run_command({"/bin/sh", "-c", "cd '" + cwd.string() + "' && exec '" + test::stand_binary().string() + "' " + args},
                           logs, tag, 300);
}

class Cli : public testing::Test {
 protected:
  CommandResult run(const std::vector<std::string>& args, const std::string& tag = "cli") const {
    return test::run_stand(args, tmp_.path(), tag, 300);
  }
  fs::path grid() const {
    if (!fs::exists(tmp_ / "short_grid.yaml")) test::write_file(tmp_ / "short_grid.yaml", kShortGrid);
    return tmp_ / "short_grid.yaml";
  }
  test::TempDir tmp_{"cli"};
};

// ---------------------------------------------------------------- options out of range

struct BadOption {
  std::vector<std::string> args;  // after the command's own
  std::string names;              // what the message must name
};

// Each exits 2 naming the option and what it takes, and makes no runs folder (nor starts a child).
TEST_F(Cli, AnOutOfRangeOptionExitsTwoBeforeAnythingStarts) {
  const fs::path runs = tmp_ / "runs";
  const std::vector<BadOption> bad = {
      {{"--speed", "-5"}, "0.01..1000"},
      {{"--speed", "5000"}, "0.01..1000"},
      {{"--speed", "0"}, "0.01..1000"},
      {{"--seed", "-1"}, "0..18446744073709551615"},
      {{"--seed", "18446744073709551616"}, "0..18446744073709551615"},
      {{"--fault", "nosuchfault"}, "unknown fault \"nosuchfault\" (expected one of "},
      {{"--fault", "sensor_glitch:rate=2"}, "rate must be in (0, 1]"},
      {{"--effect", "wobble:x=1"}, "unknown effect \"wobble\""},
      {{"--effect", "settling:amplitude_arcsec=1,tau_s=-1"}, "tau_s must be > 0"},
  };
  const std::vector<std::vector<std::string>> commands = {
      {"run", grid().string(), "--emulate", "--runs-dir", runs.string()},
      {"run", grid().string(), "--emulate", "--dry-run"},
      {"accept", "--emulate", "--runs-dir", runs.string()},
      {"investigate", "--emulate", "--model", src("calib/data/published/a-6-fpss1.json"), "--runs-dir", runs.string()},
      {"serve", "--emulate", "--runs-dir", runs.string(), "--listen", "127.0.0.1:0"},
      {"emulate", "--modbus-port", "0"},
  };
  for (const auto& command : commands) {
    for (const auto& b : bad) {
      std::vector<std::string> args = command;
      args.insert(args.end(), b.args.begin(), b.args.end());
      SCOPED_TRACE(testing::PrintToString(args));
      const CommandResult r = run(args);
      EXPECT_EQ(r.code, 2) << r.err;
      EXPECT_THAT(r.err, StartsWith("fpss-stand: error: " + b.args[0] + ": "));
      EXPECT_THAT(r.err, HasSubstr(b.names));
      EXPECT_FALSE(fs::exists(runs));
    }
  }
  // simulate takes the seed and effects too (no emulator, the same checks).
  for (const auto& b : {bad[3], bad[4], bad[7], bad[8]}) {
    std::vector<std::string> args{"simulate", "--out", (tmp_ / "rec.csv").string()};
    args.insert(args.end(), b.args.begin(), b.args.end());
    const CommandResult r = run(args);
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_THAT(r.err, HasSubstr(b.names));
    EXPECT_FALSE(fs::exists(tmp_ / "rec.csv"));
  }
  // The edges of the range are taken.
  for (const char* speed : {"0.01", "1000"}) {
    const CommandResult r = run({"run", grid().string(), "--emulate", "--dry-run", "--speed", speed});
    EXPECT_EQ(r.code, 0) << speed << r.err;
  }
}

// ---------------------------------------------------------------- one name per idea

// --unit names the unit on run, accept and emulate; the old --unit-serial still works.
TEST_F(Cli, UnitIsTheNameEverywhereAndUnitSerialStaysAnAlias) {
  for (const char* command : {"run", "accept", "emulate"}) {
    const CommandResult help = run({command, "--help"});
    EXPECT_THAT(help.out, HasSubstr("--unit,--unit-serial")) << command;
  }
  for (const char* spelling : {"--unit", "--unit-serial"}) {
    const fs::path runs = tmp_ / (std::string("runs") + spelling);
    const CommandResult r = run({"run", grid().string(), "--emulate", "--speed", "100", "--runs-dir", runs.string(),
                                 spelling, "SN-ALIAS", "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    const auto info = nlohmann::json::parse(test::read_file(test::run_dirs(runs).at(0) / "run.json"));
    EXPECT_EQ(info["unit"], "SN-ALIAS") << spelling;
  }
}

// ---------------------------------------------------------------- progress and errors

// Progress is drawn on a terminal only: into a file, none (events.log keeps it); --progress forces it.
TEST_F(Cli, ProgressOnlyOnATerminalUnlessForced) {
  const fs::path runs = tmp_ / "runs";
  const CommandResult plain = run({"run", grid().string(), "--emulate", "--speed", "100", "--runs-dir", runs.string()}, "plain");
  ASSERT_EQ(plain.code, 0) << plain.err;
  EXPECT_THAT(plain.err, Not(HasSubstr("ETA"))) << plain.err;
  const fs::path folder = test::run_dirs(runs).at(0);
  EXPECT_THAT(test::read_file(folder / "events.log"), HasSubstr("ETA"));  // kept in the run's log
  const CommandResult forced =
      run({"run", grid().string(), "--emulate", "--speed", "100", "--runs-dir", runs.string(), "--progress"}, "forced");
  ASSERT_EQ(forced.code, 0) << forced.err;
  EXPECT_THAT(forced.err, HasSubstr("\r\033[Kpoints "));
  EXPECT_THAT(forced.err, HasSubstr("ETA"));
  const CommandResult both = run({"run", grid().string(), "--emulate", "--progress", "--no-progress", "--dry-run"});
  EXPECT_EQ(both.code, 2) << both.err;
}

// A port already taken: a job that fails (exit 1), in the same style as bad input.
TEST_F(Cli, EveryErrorComesInOneStyle) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(::listen(fd, 1), 0);
  socklen_t len = sizeof a;
  ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len), 0);
  const CommandResult taken = run({"emulate", "--modbus-port", std::to_string(ntohs(a.sin_port))}, "taken");
  ::close(fd);
  EXPECT_EQ(taken.code, 1) << taken.err;
  EXPECT_THAT(taken.err, StartsWith("fpss-stand: error: ")) << taken.err;
  // A run that fails (too few offsets to fit), told under --quiet: the command's own error line.
  std::string few = kShortGrid;
  few.replace(few.find("step_deg: 0.06"), 14, "step_deg: 0.21");
  test::write_file(tmp_ / "few.yaml", few);
  const CommandResult failed = run({"run", (tmp_ / "few.yaml").string(), "--emulate", "--speed", "100", "--runs-dir",
                                    (tmp_ / "runs").string(), "--quiet"}, "failed");
  EXPECT_EQ(failed.code, 1) << failed.err;
  EXPECT_THAT(failed.err, StartsWith("fpss-stand: error: run failed: ")) << failed.err;

  const CommandResult unknown_command = run({"frobnicate"});
  const CommandResult unknown_option = run({"run", grid().string(), "--frobnicate"});
  const CommandResult missing = run({"calibrate", "--out", (tmp_ / "c.json").string()});
  const CommandResult bad_file = run({"calibrate", "--data", (tmp_ / "none.csv").string(), "--out", (tmp_ / "c.json").string()});
  for (const CommandResult* r : {&unknown_command, &unknown_option, &missing, &bad_file}) {
    EXPECT_EQ(r->code, 2) << r->err;
    EXPECT_THAT(r->err, StartsWith("fpss-stand: error: ")) << r->err;
  }
}

// What `f` writes to the console (stderr, where glog writes, and stdout, spdlog's default logger's),
// through a temporary file.
std::string console_of(const std::function<void()>& f) {
  std::fflush(stdout);
  std::fflush(stderr);
  const int saved_out = ::dup(1), saved_err = ::dup(2);
  FILE* file = std::tmpfile();
  ::dup2(::fileno(file), 1);
  ::dup2(::fileno(file), 2);
  f();
  spdlog::default_logger()->flush();
  std::fflush(stdout);
  std::fflush(stderr);
  ::dup2(saved_out, 1);
  ::dup2(saved_err, 2);
  ::close(saved_out);
  ::close(saved_err);
  std::rewind(file);
  std::string text;
  for (int c = std::fgetc(file); c != EOF; c = std::fgetc(file)) text += static_cast<char>(c);
  std::fclose(file);
  return text;
}

// --quiet's start-up call: Ceres's glog warnings and the drivers' spdlog lines no longer reach the
// console (main calls it when the parsed command's --quiet is given).
TEST(CliQuiet, QuietSilencesTheLibrariesOwnLogs) {
  const auto library_lines = [] {
    LOG(WARNING) << "Linear solver failure. Failed to compute a step: (the test's)";
    spdlog::warn("gimbal: a retry (the test's)");
  };
  const std::string loud = console_of(library_lines);
  EXPECT_THAT(loud, HasSubstr("Linear solver failure"));
  EXPECT_THAT(loud, HasSubstr("a retry"));
  cli::quiet_library_logs();
  EXPECT_EQ(console_of(library_lines), "");
}

// A run under --quiet says nothing on stderr at all.
TEST_F(Cli, AQuietRunSaysNothingOnStderr) {
  const CommandResult r = run({"run", grid().string(), "--emulate", "--speed", "100", "--runs-dir", (tmp_ / "runs").string(), "--quiet"});
  EXPECT_EQ(r.code, 0);
  EXPECT_EQ(r.err, "");
}

// ---------------------------------------------------------------- finding runs

// The demo records into build/demo/runs: `runs` and `show latest` from the checkout's root find it
// (saying so); a folder with no catalogue anywhere below says where to look.
TEST_F(Cli, RunsFindsTheCatalogueTheDemoMadeOrSaysWhereToLook) {
  const fs::path root = tmp_ / "checkout";
  fs::create_directories(root);
  const CommandResult made = stand_in(root, "run '" + grid().string() + "' --emulate --speed 100 --runs-dir build/demo/runs --quiet", tmp_.path(), "demo");
  ASSERT_EQ(made.code, 0) << made.err;
  const std::string id = nlohmann::json::parse(test::read_file(test::run_dirs(root / "build/demo/runs").at(0) / "run.json"))["run_id"];
  const CommandResult listed = stand_in(root, "runs", tmp_.path(), "runs");
  ASSERT_EQ(listed.code, 0) << listed.err;
  EXPECT_THAT(listed.out, HasSubstr(id));
  EXPECT_THAT(listed.err, HasSubstr("no catalogue at runs/stand.db; reading build/demo/runs/stand.db"));
  const CommandResult shown = stand_in(root, "show latest", tmp_.path(), "show");
  ASSERT_EQ(shown.code, 0) << shown.err;
  EXPECT_THAT(shown.out, HasSubstr("run " + id));

  fs::create_directories(tmp_ / "elsewhere");
  const CommandResult none = stand_in(tmp_ / "elsewhere", "runs", tmp_.path(), "none");
  EXPECT_EQ(none.code, 2);
  EXPECT_THAT(none.err, HasSubstr("runs/stand.db: no catalogue there"));
  EXPECT_THAT(none.err, HasSubstr("hint: a run records into RUNS_DIR/stand.db: give --runs-dir RUNS_DIR"));
  EXPECT_FALSE(fs::exists(tmp_ / "elsewhere" / "runs"));  // listing never makes a catalogue
}

// A run named by a unique prefix of its id or by `latest` (show, report, run --resume); a prefix of
// several is exit 2 naming them.
TEST_F(Cli, RunIdsByUniquePrefixAndLatest) {
  const fs::path runs = tmp_ / "runs";
  std::vector<std::string> ids;
  for (int k = 0; k < 2; ++k) {
    const CommandResult r = run({"run", grid().string(), "--emulate", "--speed", "100", "--runs-dir", runs.string(), "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
  }
  for (const auto& d : test::run_dirs(runs)) {
    ids.push_back(nlohmann::json::parse(test::read_file(d / "run.json"))["run_id"]);
  }
  ASSERT_EQ(ids.size(), 2u);
  std::sort(ids.begin(), ids.end());  // UUIDv7: in the order made
  const std::string unique = ids[1].substr(0, ids[1].size() - 4);
  const CommandResult by_prefix = run({"show", unique, "--runs-dir", runs.string()});
  ASSERT_EQ(by_prefix.code, 0) << by_prefix.err;
  EXPECT_THAT(by_prefix.out, HasSubstr("run " + ids[1]));
  const CommandResult latest = run({"show", "latest", "--runs-dir", runs.string(), "--json"});
  ASSERT_EQ(latest.code, 0) << latest.err;
  EXPECT_EQ(nlohmann::json::parse(latest.out)["run_id"], ids[1]);
  const CommandResult report = run({"report", "latest", "--runs-dir", runs.string()});
  EXPECT_EQ(report.code, 0) << report.err;

  size_t common = 0;
  while (common < ids[0].size() && ids[0][common] == ids[1][common]) ++common;
  ASSERT_GT(common, 0u);
  const CommandResult ambiguous = run({"show", ids[0].substr(0, common), "--runs-dir", runs.string()});
  EXPECT_EQ(ambiguous.code, 2);
  EXPECT_THAT(ambiguous.err, HasSubstr("ambiguous"));
  EXPECT_THAT(ambiguous.err, HasSubstr(ids[0]));
  EXPECT_THAT(ambiguous.err, HasSubstr(ids[1]));
  // --resume finds the run the same way: this one is complete, and the message names its folder.
  const CommandResult resume = run({"run", "--resume", ids[0].substr(0, ids[0].size() - 4), "--runs-dir", runs.string()});
  EXPECT_EQ(resume.code, 2) << resume.err;
  EXPECT_THAT(resume.err, HasSubstr("already completed"));
}

// ---------------------------------------------------------------- show and a diagnosis

// A run that completes with a gap: show names GAP.json's verdict and cause beside the run's PASS.
TEST_F(Cli, ShowNamesTheDiagnosisVerdictAndCause) {
  const std::string model = src("calib/data/published/a-6-fpss1.json");
  test::write_file(tmp_ / "diag.yaml", "steps:\n  - home\n"
                                       "  - null_offset_grid: {extent_deg: 0.3, step_deg: 0.1, frames: 10, settle_s: 0.2}\n"
                                       "  - diagnose: {model: " + model + ", settle_s: 0.2, partial: true}\n");
  const fs::path runs = tmp_ / "runs";
  const CommandResult r = run({"run", (tmp_ / "diag.yaml").string(), "--emulate", "--speed", "50", "--runs-dir", runs.string(),
                               "--quiet", "--effect", "bias:pitch_arcsec=6,yaw_arcsec=0"});
  ASSERT_EQ(r.code, 0) << r.err;
  const fs::path folder = test::run_dirs(runs).at(0);
  const auto gap = nlohmann::json::parse(test::read_file(folder / "GAP.json"));
  ASSERT_NE(gap["verdict"], "no_gap") << gap.dump(1);
  ASSERT_FALSE(gap["verdict_sentence"].get<std::string>().empty());
  std::string verdict = gap["verdict"];
  std::transform(verdict.begin(), verdict.end(), verdict.begin(), [](unsigned char c) { return std::toupper(c); });
  const CommandResult shown = run({"show", folder.string()});
  ASSERT_EQ(shown.code, 0) << shown.err;
  EXPECT_THAT(shown.out, HasSubstr("  diagnosis  " + verdict + ": " + gap["verdict_sentence"].get<std::string>()));
  EXPECT_THAT(shown.out, HasSubstr("             cause " + gap["cause"].get<std::string>()));
  EXPECT_THAT(shown.out, HasSubstr("(GAP.json)"));
  const auto j = nlohmann::json::parse(run({"show", folder.string(), "--json"}).out);
  EXPECT_EQ(j["diagnosis"]["verdict"], gap["verdict"]);
  EXPECT_EQ(j["diagnosis"]["cause"], gap["cause"]);
}

// ---------------------------------------------------------------- calibrate's budget

// calibrate --help's example: each axis's check says whether U holds, and if not which way it errs,
// by how much of U and what to quote; without --monte-carlo, that U is unchecked and how to check it.
TEST_F(Cli, TheBudgetMessageSaysWhatItMeans) {
  const std::string truth = src("calib/data/published/a-5-fpss2.json"), rec = (tmp_ / "rec.csv").string();
  ASSERT_EQ(run({"simulate", "--out", rec, "--truth", truth}).code, 0);
  const CommandResult checked = run({"calibrate", "--data", rec, "--out", (tmp_ / "cal.json").string(), "--truth", truth,
                                     "--monte-carlo", "100000"});
  ASSERT_EQ(checked.code, 0) << checked.err;
  const std::regex meaning(
      "the GUM budget is validated: its U holds as stated|the GUM budget is NOT validated: its \\+-U is (wider|narrower) "
      "than the Monte Carlo 95 % interval by up to [0-9.]+ arcsec \\([0-9.]+ % of U\\), beyond the tolerance; U "
      "(overstates this angle's uncertainty \\(safe but conservative\\): the interval above is the tighter figure to quote|"
      "understates this angle's uncertainty: quote the interval above, not U)\n");
  for (const char* axis : {"  pitch at ", "  yaw   at "}) {
    const auto at = checked.out.find(axis);
    ASSERT_NE(at, std::string::npos) << checked.out;
    const std::string line = checked.out.substr(at, checked.out.find('\n', at) + 1 - at);
    EXPECT_TRUE(std::regex_search(line, meaning)) << line;
  }
  const CommandResult unchecked = run({"calibrate", "--data", rec, "--out", (tmp_ / "cal2.json").string()});
  ASSERT_EQ(unchecked.code, 0) << unchecked.err;
  EXPECT_THAT(unchecked.out, HasSubstr("is the GUM's, to first order and not checked: --monte-carlo 100000 checks it"));
}

}  // namespace
}  // namespace fpss
