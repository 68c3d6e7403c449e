// Test helpers for the procedure engine and `fpss-stand run`: temp folders, files, the real binary as a child.
#pragma once
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace fpss::test {

namespace fs = std::filesystem;

inline fs::path fpss_binary() { return fs::path(FPSS_BINARY_DIR) / "stand" / "fpss-stand"; }
inline fs::path source_dir() { return fs::path(FPSS_SOURCE_DIR); }

// A fresh folder per test (ctest -j2 runs tests side by side); kept when FPSS_KEEP_TMP is set.
struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name) {
    std::string tmpl = (fs::temp_directory_path() / ("fpss-" + name + "-XXXXXX")).string();
    if (!::mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
    path = tmpl;
  }
  ~TempDir() {
    if (!std::getenv("FPSS_KEEP_TMP")) {
      std::error_code ec;
      fs::remove_all(path, ec);
    }
  }
  fs::path operator/(const std::string& s) const { return path / s; }
};

inline void write_file(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
}

inline std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Polls a condition until it holds or the (generous) timeout passes.
inline bool wait_for(const std::function<bool()>& cond, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    if (cond()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return cond();
}

// The fpss-stand binary as a child, its output in files.
class Cli {
 public:
  Cli(const std::vector<std::string>& args, const fs::path& out_dir, const std::string& tag = "cli")
      : out_(out_dir / (tag + ".out")), err_(out_dir / (tag + ".err")) {
    std::vector<std::string> argv_s{fpss_binary().string()};
    argv_s.insert(argv_s.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& s : argv_s) argv.push_back(s.data());
    argv.push_back(nullptr);
    pid_ = ::fork();
    if (pid_ == 0) {
      int o = ::open(out_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      int e = ::open(err_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(o, 1);
      ::dup2(e, 2);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
  }
  ~Cli() {
    if (pid_ > 0 && !done_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  pid_t pid() const { return pid_; }
  void signal(int sig) { ::kill(pid_, sig); }
  // Exit code, 128 + signal when killed, -1 on timeout (the child is then killed).
  int wait(double timeout_s = 180) {
    if (done_) return code_;
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    int status = 0;
    for (;;) {
      const pid_t r = ::waitpid(pid_, &status, WNOHANG);
      if (r == pid_) break;
      if (std::chrono::steady_clock::now() > end) {
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, &status, 0);
        done_ = true;
        code_ = -1;
        return code_;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    done_ = true;
    code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    return code_;
  }
  std::string out() const { return read_file(out_); }
  std::string err() const { return read_file(err_); }

 private:
  pid_t pid_ = -1;
  fs::path out_, err_;
  bool done_ = false;
  int code_ = 0;
};

// Runs the binary to completion.
struct CliResult {
  int code;
  std::string out, err;
};
inline CliResult run_cli(const std::vector<std::string>& args, const fs::path& out_dir, const std::string& tag = "cli",
                         double timeout_s = 180) {
  Cli c(args, out_dir, tag);
  const int code = c.wait(timeout_s);
  return {code, c.out(), c.err()};
}

// Run folders under a runs dir (stand.db and hidden files aside).
inline std::vector<fs::path> run_dirs(const fs::path& runs) {
  std::vector<fs::path> out;
  if (!fs::exists(runs)) return out;
  for (const auto& e : fs::directory_iterator(runs)) {
    if (e.is_directory() && e.path().filename().string()[0] != '.') out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

inline size_t count_lines(const fs::path& p) {
  std::ifstream in(p);
  size_t n = 0;
  std::string l;
  while (std::getline(in, l)) if (!l.empty()) ++n;
  return n;
}

}  // namespace fpss::test
