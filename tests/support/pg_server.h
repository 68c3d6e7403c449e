// A throw-away PostgreSQL 15 cluster for tests: initdb and pg_ctl in a temp folder, a unix socket
// there and a free loopback port; removed afterwards. PostgreSQL refuses to run as root, so under
// root (CI) every server command runs as the `postgres` system user (runuser, else setpriv) with a
// folder that user owns. Never skipped: a missing server is a failure, not a skip.
#pragma once
#include <arpa/inet.h>
#include <netinet/in.h>
#include <pwd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "tests/support/test_support.h"

namespace fpss::test {

// Where Debian's postgresql-15 puts initdb and pg_ctl; FPSS_PG_BIN overrides.
inline fs::path pg_bin_dir() {
  if (const char* e = std::getenv("FPSS_PG_BIN"); e != nullptr && *e != '\0') return e;
  return "/usr/lib/postgresql/15/bin";
}

// A loopback port nothing listens on now (the kernel's choice for port 0).
inline int free_loopback_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::runtime_error("socket failed");
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    ::close(fd);
    throw std::runtime_error("bind to a loopback port failed");
  }
  ::close(fd);
  return ntohs(a.sin_port);
}

class PgServer {
 public:
  PgServer() {
    // Under root, /tmp itself: the postgres user must traverse every folder above (a TMPDIR under
    // /root would not do), and the socket's path must stay short.
    const fs::path base = ::geteuid() == 0 ? fs::path("/tmp") : fs::temp_directory_path();
    std::string tmpl = (base / "fpss-pg-XXXXXX").string();
    if (::mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    root_ = tmpl;
    data_ = root_ / "data";
    if (::geteuid() == 0) {
      const passwd* pw = ::getpwnam("postgres");
      if (pw == nullptr) throw std::runtime_error("PgServer: running as root and there is no postgres user");
      if (::chown(root_.c_str(), pw->pw_uid, pw->pw_gid) != 0) throw std::runtime_error("chown of the pg folder failed");
      as_user_ = find_program("runuser");
      if (!as_user_.empty()) prefix_ = {as_user_, "-u", "postgres", "--"};
      else prefix_ = {find_program("setpriv"), "--reuid=postgres", "--regid=postgres", "--init-groups", "--"};
      if (prefix_[0].empty()) throw std::runtime_error("PgServer: neither runuser nor setpriv found");
    }
    logs_ = root_ / "logs";  // our own command output, written by this process
    fs::create_directories(logs_);
    run({(pg_bin_dir() / "initdb").string(), "-D", data_.string(), "-U", "fpss", "--auth=trust", "-E", "UTF8",
         "--no-sync", "--locale=C"},
        "initdb");
    for (int attempt = 0;; ++attempt) {  // a port taken between the check and the start: another
      port_ = free_loopback_port();
      write_conf();
      if (try_start()) break;
      if (attempt == 4) throw std::runtime_error("PgServer: the server would not start:\n" + log());
    }
    run({(pg_bin_dir() / "createdb").string(), "-h", root_.string(), "-p", std::to_string(port_), "-U", "fpss",
         "fpss"},
        "createdb");
  }
  ~PgServer() {
    if (running_) {
      try {
        run({(pg_bin_dir() / "pg_ctl").string(), "-D", data_.string(), "-m", "immediate", "-w", "stop"}, "stop");
      } catch (const std::exception&) {
      }
    }
    if (std::getenv("FPSS_KEEP_TMP") == nullptr) {
      std::error_code ec;
      fs::remove_all(root_, ec);
    }
  }
  PgServer(const PgServer&) = delete;
  PgServer& operator=(const PgServer&) = delete;

  int port() const { return port_; }
  // A URL to database `db` (created by create_database; "fpss" always exists) over loopback TCP.
  std::string url(const std::string& db = "fpss") const {
    return "postgresql://fpss@127.0.0.1:" + std::to_string(port_) + "/" + db + "?sslmode=disable";
  }
  // A fresh database per test, so tests of one server never see each other's rows.
  std::string create_database(const std::string& name) {
    run({(pg_bin_dir() / "createdb").string(), "-h", root_.string(), "-p", std::to_string(port_), "-U", "fpss",
         name},
        "createdb-" + name);
    return url(name);
  }
  // SQL through psql (as the cluster's superuser): for tests that change what the server holds.
  std::string psql(const std::string& db, const std::string& sql) {
    return run({(pg_bin_dir() / "psql").string(), "-h", root_.string(), "-p", std::to_string(port_), "-U", "fpss",
                "-d", db, "-v", "ON_ERROR_STOP=1", "-At", "-c", sql},
               "psql");
  }
  void stop() {
    run({(pg_bin_dir() / "pg_ctl").string(), "-D", data_.string(), "-m", "fast", "-w", "stop"}, "stop");
    running_ = false;
  }
  void start() {
    if (!try_start()) throw std::runtime_error("PgServer: restart failed:\n" + log());
  }
  void restart() {
    run({(pg_bin_dir() / "pg_ctl").string(), "-D", data_.string(), "-m", "fast", "-w", "-l",
         (root_ / "server.log").string(), "restart"},
        "restart");
    running_ = true;
  }
  std::string log() const { return fs::exists(root_ / "server.log") ? read_file(root_ / "server.log") : ""; }

 private:
  // The settings in a file postgresql.conf includes, never through pg_ctl -o (which a shell reads).
  // Written by this process (root may write the postgres user's folder; the file stays readable).
  void write_conf() {
    write_file(data_ / "fpss_test.conf",
               "listen_addresses = '127.0.0.1'\nport = " + std::to_string(port_) + "\nunix_socket_directories = '" +
                   root_.string() +
                   "'\nfsync = off\nsynchronous_commit = off\nfull_page_writes = off\nmax_connections = 100\n"
                   "shared_buffers = 16MB\n");
    if (!included_) {
      std::ofstream(data_ / "postgresql.conf", std::ios::app) << "\ninclude 'fpss_test.conf'\n";
      included_ = true;
    }
  }
  bool try_start() {
    const auto r = command({(pg_bin_dir() / "pg_ctl").string(), "-D", data_.string(), "-l",
                            (root_ / "server.log").string(), "-w", "-t", "60", "start"},
                           "start");
    running_ = r.code == 0;
    return running_;
  }
  CommandResult command(std::vector<std::string> argv, const std::string& tag) {
    std::vector<std::string> full = prefix_;
    full.insert(full.end(), argv.begin(), argv.end());
    return run_command(full, logs_, tag, 120);
  }
  std::string run(std::vector<std::string> argv, const std::string& tag) {
    const auto r = command(argv, tag);
    if (r.code != 0) {
      throw std::runtime_error("PgServer: " + argv[0] + " exited " + std::to_string(r.code) + ": " + r.err + r.out);
    }
    return r.out;
  }

  fs::path root_, data_, logs_;
  std::string as_user_;
  std::vector<std::string> prefix_;
  int port_ = 0;
  bool running_ = false, included_ = false;
};

}  // namespace fpss::test
