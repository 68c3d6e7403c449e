// Test helpers below the wire: a real pty pair, a loopback TCP listener, the fake sensor electronics.
#pragma once
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <atomic>
#include <functional>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "drivers/fpss_frame.h"
#include "tests/support/test_support.h"

namespace fpss::test {

inline void write_all(int fd, const uint8_t* d, std::size_t n) {
  while (n > 0) {
    ssize_t w = ::write(fd, d, n);
    if (w < 0 && (errno == EINTR || errno == EAGAIN)) {
      pollfd p{fd, POLLOUT, 0};
      ::poll(&p, 1, 100);
      continue;
    }
    if (w <= 0) throw std::runtime_error("test write failed");
    d += w;
    n -= static_cast<std::size_t>(w);
  }
}

// The master side of a real pseudo-terminal; the driver opens slave_path().
class PtyPair {
 public:
  PtyPair() {
    master_ = ::posix_openpt(O_RDWR | O_NOCTTY);
    if (master_ < 0 || ::grantpt(master_) != 0 || ::unlockpt(master_) != 0) throw std::runtime_error("posix_openpt");
    slave_path_ = ::ptsname(master_);
    termios t{};
    ::tcgetattr(master_, &t);
    ::cfmakeraw(&t);  // no echo, no line editing: bytes pass as they are
    ::tcsetattr(master_, TCSANOW, &t);
  }
  ~PtyPair() { close_master(); }
  int master() const { return master_; }
  const std::string& slave_path() const { return slave_path_; }
  void close_master() {
    if (master_ >= 0) ::close(master_);
    master_ = -1;
  }

 private:
  int master_ = -1;
  std::string slave_path_;
};

// A listening socket on 127.0.0.1 with an ephemeral port.
class TcpListener {
 public:
  TcpListener() {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    int one = 1;
    ::setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(fd_, 4) != 0)
      throw std::runtime_error("bind/listen");
    socklen_t len = sizeof a;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
  }
  ~TcpListener() { close(); }
  int port() const { return port_; }
  // Waits up to timeout_s for a client; -1 if none.
  int accept(double timeout_s = 10.0) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(timeout_s * 1000)) <= 0) return -1;
    return ::accept4(fd_, nullptr, nullptr, SOCK_CLOEXEC);
  }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_ = -1;
  int port_ = 0;
};

// A loopback port that is bound but never listens: connecting is refused, and no other process
// can take the port while this object lives (a freed ephemeral port could be reused under ctest -j).
class RefusingPort {
 public:
  RefusingPort() {
    fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) throw std::runtime_error("bind");
    socklen_t len = sizeof a;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
  }
  ~RefusingPort() { ::close(fd_); }
  int port() const { return port_; }

 private:
  int fd_ = -1;
  int port_ = 0;
};

// The sensor electronics as the test plays them on the far end of a pty or socket: answers command
// lines through a handler and lets the test write sample frames, garbage and corrupt frames.
class FakeElectronics {
 public:
  using Handler = std::function<std::optional<std::string>(const std::string& line)>;
  explicit FakeElectronics(int fd, Handler h = nullptr) : fd_(fd), handler_(std::move(h)) {
    thread_ = std::thread([this] { loop(); });
  }
  ~FakeElectronics() { stop(); }
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  void set_handler(Handler h) {
    std::lock_guard lk(mu_);
    handler_ = std::move(h);
  }
  void write_bytes(const std::vector<uint8_t>& b) {
    std::lock_guard lk(write_mu_);
    write_all(fd_, b.data(), b.size());
  }
  void write_frame(const frame::Frame& f) { write_bytes(frame::encode(f)); }
  std::vector<std::string> lines() const {
    std::lock_guard lk(mu_);
    return lines_;
  }

 private:
  void loop() {
    std::string pending;
    char buf[256];
    while (!stop_) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 10) <= 0 || !(p.revents & POLLIN)) continue;
      ssize_t n = ::read(fd_, buf, sizeof buf);
      if (n <= 0) continue;
      pending.append(buf, static_cast<std::size_t>(n));
      for (auto nl = pending.find('\n'); nl != std::string::npos; nl = pending.find('\n')) {
        std::string line = pending.substr(0, nl);
        pending.erase(0, nl + 1);
        Handler h;
        {
          std::lock_guard lk(mu_);
          lines_.push_back(line);
          h = handler_;
        }
        if (!h) continue;
        if (auto reply = h(line)) write_frame(frame::Reply{*reply});
      }
    }
  }
  int fd_;
  std::atomic<bool> stop_{false};
  mutable std::mutex mu_;
  std::mutex write_mu_;
  Handler handler_;
  std::vector<std::string> lines_;
  std::thread thread_;
};

}  // namespace fpss::test
