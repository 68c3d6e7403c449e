// What every test area needs: per-test temp folders, files, waiting on a condition, thrown messages, child processes.
#pragma once
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "base/unique_fd.h"

extern char** environ;

namespace fpss::test {

namespace fs = std::filesystem;

// FPSS_BINARY_DIR comes from fpss_add_test (and the benchmarks that run the binary).
// A program on PATH, found as exec would find it (no shell); "" when there is none.
inline std::string find_program(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/bin:/bin";
  size_t start = 0;
  while (start <= dirs.size()) {
    const size_t end = std::min(dirs.find(':', start), dirs.size());
    const std::string d = dirs.substr(start, end - start);
    const std::string p = (d.empty() ? std::string(".") : d) + "/" + name;
    if (::access(p.c_str(), X_OK) == 0) return p;
    start = end + 1;
  }
  return "";
}

inline fs::path stand_binary() { return fs::path(FPSS_BINARY_DIR) / "stand" / "fpss-stand"; }
inline fs::path source_dir() { return fs::path(FPSS_SOURCE_DIR); }

// Runs `body` in a forked child; the child exits 0 when body returns, 1 when it throws (the
// message on stderr).
inline pid_t fork_child(const std::function<void()>& body) {
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error("fork failed");
  if (pid == 0) {
    int code = 0;
    try {
      body();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "child %d: %s\n", ::getpid(), e.what());
      code = 1;
    }
    std::fflush(nullptr);
    ::_exit(code);
  }
  return pid;
}

// ---------------------------------------------------------------- files

inline std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The folder in `runs_dir` whose run.json names `run_id` (the catalogue's UUIDv7; folders keep
// readable names); `runs_dir / run_id` when none does yet.
inline fs::path run_folder_of(const fs::path& runs_dir, const std::string& run_id) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(runs_dir, ec)) {
    if (!e.is_directory()) continue;
    if (read_file(e.path() / "run.json").find("\"" + run_id + "\"") != std::string::npos) return e.path();
  }
  return runs_dir / run_id;
}

inline fs::path write_file(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
  return p;
}

// A fresh folder per test under the system temp dir, removed with everything in it (ctest -j2 runs
// tests side by side, so never a fixed name); kept when FPSS_KEEP_TMP is set, to look at after a failure.
class TempDir {
 public:
  explicit TempDir(const std::string& tag = "test") {
    std::string tmpl = (fs::temp_directory_path() / ("fpss-" + tag + "-XXXXXX")).string();
    if (!::mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp " + tmpl + " failed");
    path_ = tmpl;
  }
  ~TempDir() {
    if (std::getenv("FPSS_KEEP_TMP")) return;
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const fs::path& path() const { return path_; }
  fs::path operator/(const std::string& name) const { return path_ / name; }
  // Writes a small fixture file (CSV, JSON, YAML) into the folder and returns its path.
  fs::path write(const std::string& name, const std::string& text) const { return write_file(path_ / name, text); }

 private:
  fs::path path_;
};

// ---------------------------------------------------------------- waiting and errors

// Polls a condition until it holds or the (generous) timeout passes; never asserts how long it took.
// [[nodiscard]]: a test that waits asserts that what it waited for came (-Werror makes it a build error).
[[nodiscard]] inline bool wait_until(const std::function<bool()>& cond, double timeout_s = 10.0,
                       std::chrono::milliseconds poll = std::chrono::milliseconds(2)) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    if (cond()) return true;
    std::this_thread::sleep_for(poll);
  }
  return cond();
}

// The message of the E that f throws, "(no exception)" when it returns; any other exception goes on.
template <class E = std::exception, class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "(no exception)";
}

// The message of the first E that f throws when called again and again (a hang-up the link notices
// on a later read, say); nullopt when it has not thrown within timeout_s.
template <class E = std::exception, class F>
std::optional<std::string> error_within(F&& f, double timeout_s = 10.0) {
  std::optional<std::string> msg;
  // The caller asserts on the nullopt (a link that never noticed the hang-up).
  (void)wait_until(
      [&] {
        try {
          f();
        } catch (const E& e) {
          msg = e.what();
          return true;
        }
        return false;
      },
      timeout_s);
  return msg;
}

// ---------------------------------------------------------------- child processes

// Exit code of a child, 128 + signal when a signal ended it, -1 if it cannot be waited for.
inline int wait_exit_code(pid_t pid) {
  int status = 0;
  pid_t r;
  while ((r = ::waitpid(pid, &status, 0)) < 0 && errno == EINTR) {
  }
  if (r != pid) return -1;
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}

// How children started together ended: each one's exit code (as wait_exit_code gives it), and the
// seconds from their release to the last one's end.
struct TogetherDone {
  std::vector<int> exit_codes;
  double seconds = 0;
};

// Runs body(0) .. body(n - 1) in n forked children (as fork_child) released at one moment: each
// waits until a pipe closes, which the parent does once all are forked. Waits for them all.
inline TogetherDone fork_together(int n, const std::function<void(int)>& body) {
  int go[2];
  if (::pipe(go) != 0) throw std::runtime_error("pipe failed");
  std::vector<pid_t> kids;
  for (int i = 0; i < n; ++i) {
    kids.push_back(fork_child([&, i] {
      ::close(go[1]);
      char c;
      if (::read(go[0], &c, 1) != 0) throw std::runtime_error("barrier");  // end of file: all start together
      body(i);
    }));
  }
  ::close(go[0]);
  const auto t0 = std::chrono::steady_clock::now();
  ::close(go[1]);
  TogetherDone done;
  for (pid_t k : kids) done.exit_codes.push_back(wait_exit_code(k));
  done.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return done;
}

// A program started as a child: stdout into a file, or (out_file empty) into a pipe the test reads
// line by line; stderr into a file. A child still running when the object goes is killed and reaped.
class Child {
 public:
  static constexpr double kForever = std::numeric_limits<double>::infinity();

  Child(std::vector<std::string> argv, fs::path out_file, fs::path err_file)
      : out_path_(std::move(out_file)), err_path_(std::move(err_file)) {
    int fds[2] = {-1, -1};
    if (out_path_.empty() && ::pipe2(fds, O_CLOEXEC) != 0) throw std::runtime_error("pipe failed");
    UniqueFd read_end(fds[0]), write_end(fds[1]);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    if (out_path_.empty()) {
      posix_spawn_file_actions_adddup2(&fa, fds[1], 1);
    } else {
      posix_spawn_file_actions_addopen(&fa, 1, out_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    }
    posix_spawn_file_actions_addopen(&fa, 2, err_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<char*> args;
    for (auto& a : argv) args.push_back(a.data());
    args.push_back(nullptr);
    const int rc = ::posix_spawn(&pid_, args[0], &fa, nullptr, args.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    write_end.reset();  // the child has its own copy
    if (rc != 0) {
      pid_ = -1;
      throw std::runtime_error("posix_spawn " + argv[0] + " failed");
    }
    pipe_ = std::move(read_end);
  }
  ~Child() {
    if (pid_ > 0 && !done_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  pid_t pid() const { return pid_; }
  void signal(int sig) {
    if (pid_ > 0 && !done_) ::kill(pid_, sig);  // never a reaped (perhaps reused) pid
  }

  // Exit code, 128 + signal when killed; -1 if it has not ended within timeout_s (it is then killed).
  int wait(double timeout_s = kForever) {
    if (done_) return code_;
    if (timeout_s == kForever) {
      code_ = wait_exit_code(pid_);
    } else {
      const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
      int status = 0;
      while (::waitpid(pid_, &status, WNOHANG) != pid_) {
        if (std::chrono::steady_clock::now() > end) {
          ::kill(pid_, SIGKILL);
          ::waitpid(pid_, nullptr, 0);
          done_ = true;
          code_ = -1;
          return code_;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    }
    done_ = true;
    return code_;
  }

  // The next stdout line (pipe mode), or nullopt at end of file or after timeout_s.
  std::optional<std::string> line(double timeout_s = 30.0) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    for (;;) {
      if (auto nl = buf_.find('\n'); nl != std::string::npos) {
        std::string l = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return l;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
      if (left.count() <= 0 || !pipe_) return std::nullopt;
      pollfd p{pipe_.get(), POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
      char b[4096];
      const ssize_t n = ::read(pipe_.get(), b, sizeof b);
      if (n <= 0) return std::nullopt;
      buf_.append(b, static_cast<std::size_t>(n));
    }
  }

  std::string out() const { return out_path_.empty() ? std::string() : read_file(out_path_); }
  std::string err() const { return read_file(err_path_); }

 private:
  pid_t pid_ = -1;
  UniqueFd pipe_;
  fs::path out_path_, err_path_;
  std::string buf_;
  bool done_ = false;
  int code_ = -1;
};

// How a program run to its end went.
struct CommandResult {
  int code = -1;
  std::string out, err;
};

// Runs argv to its end; stdout and stderr go to <tag>.out and <tag>.err in dir.
inline CommandResult run_command(const std::vector<std::string>& argv, const fs::path& dir,
                                 const std::string& tag = "cli", double timeout_s = Child::kForever) {
  Child c(argv, dir / (tag + ".out"), dir / (tag + ".err"));
  const int code = c.wait(timeout_s);
  return {code, c.out(), c.err()};
}

inline std::vector<std::string> stand_argv(const std::vector<std::string>& args) {
  std::vector<std::string> argv{stand_binary().string()};
  argv.insert(argv.end(), args.begin(), args.end());
  return argv;
}

// `fpss-stand args...` as a child, its output in <tag>.out and <tag>.err in dir.
inline Child start_stand(const std::vector<std::string>& args, const fs::path& dir, const std::string& tag = "cli") {
  return Child(stand_argv(args), dir / (tag + ".out"), dir / (tag + ".err"));
}

// `fpss-stand emulate args...` as a child: stdout on a pipe (its ready lines, read with line()), stderr into err_file.
inline Child start_emulate(const std::vector<std::string>& args, const fs::path& err_file) {
  std::vector<std::string> argv{stand_binary().string(), "emulate"};
  argv.insert(argv.end(), args.begin(), args.end());
  return Child(std::move(argv), fs::path(), err_file);
}

// `fpss-stand args...` to its end; -1 (and the child killed) if it takes longer than timeout_s.
inline CommandResult run_stand(const std::vector<std::string>& args, const fs::path& dir,
                               const std::string& tag = "cli", double timeout_s = 180) {
  return run_command(stand_argv(args), dir, tag, timeout_s);
}

// The same with the arguments as shell words (quotes and all), for tests that write their command
// lines as text; no time limit of its own (ctest's applies).
inline CommandResult run_stand_shell(const std::string& args, const fs::path& dir, const std::string& tag = "cli") {
  if (!fs::exists(stand_binary())) throw std::runtime_error(stand_binary().string() + " is not built");
  return run_command({"/bin/sh", "-c", "exec '" + stand_binary().string() + "' " + args}, dir, tag);
}

// ---------------------------------------------------------------- small file systems

// A tmpfs of `size` (e.g. "64k") mounted on a fresh folder, read-only when asked: a full disk or a
// read-only folder even for root. mounted() is false where mounting is not allowed (not root, a
// container without CAP_SYS_ADMIN): tests then skip with GTEST_SKIP.
class SmallTmpfs {
 public:
  explicit SmallTmpfs(const std::string& size, bool read_only = false) : dir_("tmpfs") {
    const std::string opts = "size=" + size + ",mode=0755";
    mounted_ = ::mount("tmpfs", dir_.path().c_str(), "tmpfs", read_only ? MS_RDONLY : 0, opts.c_str()) == 0;
  }
  ~SmallTmpfs() {
    if (mounted_) ::umount2(dir_.path().c_str(), MNT_DETACH);
  }
  SmallTmpfs(const SmallTmpfs&) = delete;
  SmallTmpfs& operator=(const SmallTmpfs&) = delete;

  bool mounted() const { return mounted_; }
  const fs::path& path() const { return dir_.path(); }
  fs::path operator/(const std::string& name) const { return dir_.path() / name; }

 private:
  TempDir dir_;
  bool mounted_ = false;
};

}  // namespace fpss::test
