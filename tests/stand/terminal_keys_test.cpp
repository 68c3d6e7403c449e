// The operator's terminal: `fpss-stand run` with stdin, stdout and stderr on a real pty (its
// controlling terminal): keys p/r/a, Ctrl-C, the terminal's settings restored however it ends,
// and Table 1 with the check result after the progress line.
#include <gtest/gtest.h>
#include <stdlib.h>
#include <sys/ioctl.h>
#include <termios.h>

#include <atomic>
#include <mutex>

#include <nlohmann/json.hpp>

#include "tests/procedures/run_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

// fpss-stand in a new session whose controlling terminal is a fresh pty; a thread keeps the
// master drained (the run writes its progress there) and keeps what it read.
class PtyRun {
 public:
  // `own_terminal`: the pty is the child's controlling terminal and it is the foreground job;
  // false: its stdin is a terminal it does not own (as for a job in the background).
  explicit PtyRun(const std::vector<std::string>& args, bool own_terminal = true) {
    master_ = ::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
    if (master_ < 0 || ::grantpt(master_) != 0 || ::unlockpt(master_) != 0) throw std::runtime_error("no pty");
    slave_path_ = ::ptsname(master_);
    // The test's own handle on the terminal, to look at its settings (never its controlling terminal).
    slave_ = ::open(slave_path_.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
    if (slave_ < 0) throw std::runtime_error("cannot open " + slave_path_);
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    if (own_terminal) posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSID);  // before the opens: the pty becomes its terminal
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, slave_path_.c_str(), own_terminal ? O_RDWR : O_RDWR | O_NOCTTY, 0);
    posix_spawn_file_actions_adddup2(&fa, 0, 1);
    posix_spawn_file_actions_adddup2(&fa, 0, 2);
    std::vector<std::string> argv = test::stand_argv(args);
    std::vector<char*> cargv;
    for (auto& a : argv) cargv.push_back(a.data());
    cargv.push_back(nullptr);
    const int rc = ::posix_spawn(&pid_, cargv[0], &fa, &attr, cargv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    posix_spawnattr_destroy(&attr);
    if (rc != 0) throw std::runtime_error("posix_spawn failed");
    reader_ = std::thread([this] { drain(); });
  }
  ~PtyRun() {
    if (!done_) {
      ::kill(pid_, SIGKILL);
      test::wait_exit_code(pid_);
    }
    stop_ = true;
    if (reader_.joinable()) reader_.join();
    ::close(slave_);
    ::close(master_);
  }

  void type(const std::string& keys) { ASSERT_EQ(::write(master_, keys.data(), keys.size()), static_cast<ssize_t>(keys.size())); }
  void signal(int sig) { ::kill(pid_, sig); }
  int wait(double timeout_s = 180) {
    int code = -1;
    // -1 when it did not exit in time: the caller's expected exit code fails on it.
    (void)test::wait_until([&] {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) != pid_) return false;
      code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      return true;
    }, timeout_s, std::chrono::milliseconds(10));
    done_ = code != -1;
    if (done_) {
      // All it wrote before it exited is in the terminal's buffer: read to the end here, not when
      // the reader's next poll comes round (output() right after would miss the last lines).
      stop_ = true;
      if (reader_.joinable()) reader_.join();
      while (read_some(0)) {}
    }
    return code;
  }
  // The terminal's local modes as the line discipline holds them now.
  tcflag_t lflag() const {
    termios t{};
    ::tcgetattr(slave_, &t);
    return t.c_lflag;
  }
  bool keys_mode() const { return (lflag() & (ICANON | ECHO)) == 0; }
  bool cooked_mode() const { return (lflag() & (ICANON | ECHO)) == (ICANON | ECHO); }
  std::string output() {
    std::lock_guard lock(mu_);
    return out_;
  }

 private:
  void drain() {
    while (!stop_) read_some(20);
  }
  // Reads what the terminal holds within timeout_ms; false when nothing came.
  bool read_some(int timeout_ms) {
    pollfd p{master_, POLLIN, 0};
    if (::poll(&p, 1, timeout_ms) <= 0) return false;
    char b[4096];
    const ssize_t n = ::read(master_, b, sizeof b);
    if (n <= 0) return false;
    std::lock_guard lock(mu_);
    out_.append(b, static_cast<size_t>(n));
    return true;
  }

  int master_ = -1, slave_ = -1;
  std::string slave_path_;
  pid_t pid_ = -1;
  bool done_ = false;
  std::atomic<bool> stop_{false};
  std::thread reader_;
  std::mutex mu_;
  std::string out_;
};

std::string grid() { return (test::source_dir() / "procedures" / "discrete_grid.yaml").string(); }

fs::path the_run(const fs::path& runs) {
  const auto d = test::run_dirs(runs);
  return d.empty() ? fs::path() : d.front();
}

std::string events_of(const fs::path& runs) {
  const fs::path run = the_run(runs);
  return run.empty() ? std::string() : test::read_file(run / "events.jsonl");
}

size_t points_of(const fs::path& runs) { return test::journaled_points(runs); }

// p holds the gimbal after the point in progress, r goes on, a stops at the safe state; the
// terminal is in key mode while the run listens and as it was once the run ends.
TEST(TerminalKeys, PauseResumeAndAbortFromTheKeyboard) {
  TempDir tmp("keys");
  const fs::path runs = tmp / "runs";
  PtyRun run({"run", grid(), "--emulate", "--runs-dir", runs.string()});
  ASSERT_TRUE(test::wait_until([&] { return points_of(runs) >= 3; }, 120)) << run.output();
  EXPECT_TRUE(run.keys_mode()) << "lflag " << run.lflag();
  run.type("p");
  ASSERT_TRUE(test::wait_until([&] { return events_of(runs).find("\"type\":\"paused\"") != std::string::npos; }, 60))
      << run.output();
  // Paused: the journal stops growing (the engine waits for the key; no timing is asserted, only
  // that what is durable at the pause is what is durable a moment later under the same pause).
  const size_t at_pause = points_of(runs);
  EXPECT_TRUE(test::wait_until([&] { return run.output().find("operator: pause") != std::string::npos; }, 30));
  EXPECT_EQ(points_of(runs), at_pause);
  run.type("r");
  ASSERT_TRUE(test::wait_until([&] { return events_of(runs).find("\"type\":\"resumed\"") != std::string::npos; }, 60))
      << run.output();
  ASSERT_TRUE(test::wait_until([&] { return points_of(runs) > at_pause; }, 60));
  run.type("a");
  EXPECT_EQ(run.wait(), 1) << run.output();
  const nlohmann::json doc = nlohmann::json::parse(test::read_file(the_run(runs) / "run.json"));
  EXPECT_EQ(doc["outcome"], "interrupted") << doc.dump();
  EXPECT_EQ(doc["stop_cause"], "aborted");
  EXPECT_EQ(doc["safe_state"], true);
  EXPECT_LT(doc["points"]["completed"].get<int64_t>(), doc["points"]["total"].get<int64_t>());
  EXPECT_TRUE(run.cooked_mode()) << "lflag " << run.lflag();
  const std::string out = run.output();
  EXPECT_NE(out.find("keys: p pause, r resume, a abort"), std::string::npos) << out;
  EXPECT_NE(out.find("operator: abort"), std::string::npos) << out;
  EXPECT_NE(out.find("resume with: fpss-stand run --resume"), std::string::npos) << out;  // points are missing
}

// `accept` takes the same keys: an abort stops the run with no verdict.
TEST(TerminalKeys, AcceptTakesTheKeysToo) {
  TempDir tmp("keys-accept");
  const fs::path runs = tmp / "runs";
  PtyRun run({"accept", "--emulate", "--runs-dir", runs.string()});
  ASSERT_TRUE(test::wait_until([&] { return points_of(runs) >= 2 && run.keys_mode(); }, 120)) << run.output();
  run.type("a");
  EXPECT_EQ(run.wait(), 1) << run.output();
  EXPECT_NE(run.output().find("no verdict"), std::string::npos) << run.output();
  const nlohmann::json doc = nlohmann::json::parse(test::read_file(the_run(runs) / "run.json"));
  EXPECT_EQ(doc["stop_cause"], "aborted");
  EXPECT_TRUE(run.cooked_mode()) << "lflag " << run.lflag();
}

// Ctrl-C on the terminal interrupts as before (the line discipline's SIGINT), and the terminal
// comes back; a signal that ends the process outright (SIGQUIT) restores it too.
TEST(TerminalKeys, CtrlCInterruptsAndEveryEndRestoresTheTerminal) {
  TempDir tmp("keys-sig");
  {
    const fs::path runs = tmp / "runs-int";
    PtyRun run({"run", grid(), "--emulate", "--runs-dir", runs.string()});
    ASSERT_TRUE(test::wait_until([&] { return points_of(runs) >= 2 && run.keys_mode(); }, 120)) << run.output();
    run.type("\x03");
    EXPECT_EQ(run.wait(), 1) << run.output();
    const nlohmann::json doc = nlohmann::json::parse(test::read_file(the_run(runs) / "run.json"));
    EXPECT_EQ(doc["stop_cause"], "interrupted");
    EXPECT_TRUE(run.cooked_mode()) << "lflag " << run.lflag();
  }
  {
    const fs::path runs = tmp / "runs-quit";
    PtyRun run({"run", grid(), "--emulate", "--runs-dir", runs.string()});
    ASSERT_TRUE(test::wait_until([&] { return points_of(runs) >= 2 && run.keys_mode(); }, 120)) << run.output();
    run.signal(SIGQUIT);
    EXPECT_EQ(run.wait(), 128 + SIGQUIT) << run.output();
    EXPECT_TRUE(run.cooked_mode()) << "lflag " << run.lflag();
  }
}

// A terminal on stdin that is not the run's own foreground terminal (a job in the background)
// is left alone: no key mode (which would stop the job with SIGTTOU), nothing read from it.
TEST(TerminalKeys, ATerminalThatIsNotTheRunsForegroundIsLeftAlone) {
  TempDir tmp("keys-bg");
  const fs::path runs = tmp / "runs";
  PtyRun run({"run", grid(), "--emulate", "--speed", "50", "--runs-dir", runs.string()}, false);
  ASSERT_TRUE(test::wait_until([&] { return points_of(runs) >= 3; }, 120)) << run.output();
  EXPECT_TRUE(run.cooked_mode()) << "lflag " << run.lflag();
  run.type("a\n");  // not read: the run goes on to its end
  EXPECT_EQ(run.wait(), 0) << run.output();
  EXPECT_EQ(run.output().find("keys: p pause"), std::string::npos) << run.output();
  EXPECT_EQ(test::journaled_points(runs), 113u);
}

// On a terminal the log lines are hidden behind the live line; Table 1 and the check result are
// still printed once it is done, as they are in a log.
TEST(TerminalKeys, TableOneAndTheCheckFollowTheProgressLine) {
  TempDir tmp("keys-summary");
  const fs::path runs = tmp / "runs";
  PtyRun run({"run", grid(), "--emulate", "--speed", "50", "--runs-dir", runs.string()});
  EXPECT_EQ(run.wait(), 0) << run.output();
  EXPECT_TRUE(run.cooked_mode());
  const std::string out = run.output();
  const size_t progress = out.rfind("points 113/113");
  const size_t table = out.find("mean residual (arcsec)");
  const size_t check = out.find("check: residuals within the limits");
  ASSERT_NE(progress, std::string::npos) << out;
  ASSERT_NE(table, std::string::npos) << out;
  ASSERT_NE(check, std::string::npos) << out;
  EXPECT_LT(progress, table);
  EXPECT_LT(table, check);
  EXPECT_EQ(out.find("resume with:"), std::string::npos) << out;  // nothing is missing
}

}  // namespace
}  // namespace fpss
