// Byte streams: termios for ptys, TCP sockets for terminal servers, libserialport for real ports.
#include "drivers/byte_stream.h"

#include <fcntl.h>
#include <libserialport.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <termios.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "base/unique_fd.h"
#include "drivers/endpoints.h"

namespace fpss {
namespace {

int to_ms(double s) {
  if (!(s > 0)) return 0;
  return static_cast<int>(std::min(std::ceil(s * 1000.0), 2.0e9));
}

std::string errno_text(int e) { return fmt::format("{} (errno {})", std::strerror(e), e); }

using Clock = std::chrono::steady_clock;

// Shared by the pty and TCP streams: a non-blocking file descriptor driven by poll().
class FdStream : public ByteStream {
 public:
  explicit FdStream(std::string endpoint) : endpoint_(std::move(endpoint)) {}
  ~FdStream() override { FdStream::close(); }
  void close() override { fd_.reset(); }
  bool is_open() const override { return static_cast<bool>(fd_); }
  const std::string& endpoint() const override { return endpoint_; }

  std::size_t read(uint8_t* buf, std::size_t n, double timeout_s) override {
    if (!fd_) throw DeviceError(fmt::format("{}: read on a closed link", endpoint_));
    pollfd p{fd_.get(), POLLIN, 0};
    int rc;
    do rc = ::poll(&p, 1, to_ms(timeout_s));
    while (rc < 0 && errno == EINTR);
    if (rc < 0) lost("poll", errno);
    if (rc == 0) return 0;
    // Read what is there even on POLLHUP: the last bytes before a hang-up still count.
    ssize_t got;
    do got = recv_some(buf, n);
    while (got < 0 && errno == EINTR);
    if (got > 0) return static_cast<std::size_t>(got);
    if (got < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      if (p.revents & (POLLHUP | POLLERR | POLLNVAL)) lost_hangup();
      return 0;
    }
    if (got == 0) lost_hangup();
    lost("read", errno);
  }

  void write(const uint8_t* data, std::size_t n, double timeout_s) override {
    if (!fd_) throw DeviceError(fmt::format("{}: write on a closed link", endpoint_));
    auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
    std::size_t done = 0;
    while (done < n) {
      ssize_t w = send_some(data + done, n - done);
      if (w > 0) {
        done += static_cast<std::size_t>(w);
        continue;
      }
      if (w < 0 && errno == EINTR) continue;
      if (w < 0 && errno != EAGAIN && errno != EWOULDBLOCK) lost("write", errno);
      double left = std::chrono::duration<double>(deadline - Clock::now()).count();
      if (left <= 0)
        throw DeviceError(fmt::format("{}: write timed out after {} s with {} of {} bytes sent", endpoint_,
                                      timeout_s, done, n));
      pollfd p{fd_.get(), POLLOUT, 0};
      if (::poll(&p, 1, to_ms(left)) < 0 && errno != EINTR) lost("poll", errno);
    }
  }

 protected:
  virtual ssize_t recv_some(uint8_t* buf, std::size_t n) { return ::read(fd_.get(), buf, n); }
  virtual ssize_t send_some(const uint8_t* data, std::size_t n) { return ::write(fd_.get(), data, n); }
  // The descriptor stays open: another thread may be blocked on it; the owner closes.
  [[noreturn]] void lost(const char* what, int e) {
    throw DeviceError(fmt::format("{}: {} failed: {}; link lost", endpoint_, what, errno_text(e)));
  }
  [[noreturn]] void lost_hangup() {
    throw DeviceError(fmt::format("{}: the other end hung up (EOF); link lost", endpoint_));
  }

  std::string endpoint_;
  UniqueFd fd_;
};

// A pseudo-terminal slave: plain POSIX termios, raw 115200 8N1, no flow control.
class PtyStream final : public FdStream {
 public:
  PtyStream(std::string endpoint, std::string path) : FdStream(std::move(endpoint)), path_(std::move(path)) {}
  void open() override {
    close();
    UniqueFd fd(::open(path_.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC));
    if (!fd) throw DeviceError(fmt::format("{}: cannot open {}: {}", endpoint_, path_, errno_text(errno)));
    termios t{};
    if (::tcgetattr(fd.get(), &t) != 0) {
      int e = errno;
      throw DeviceError(fmt::format("{}: {} is not a terminal (tcgetattr: {})", endpoint_, path_, errno_text(e)));
    }
    ::cfmakeraw(&t);
    t.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | CRTSCTS | PARENB | CSIZE);
    t.c_cflag |= CS8 | CLOCAL | CREAD;
    t.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
    t.c_cc[VMIN] = 0;
    t.c_cc[VTIME] = 0;
    ::cfsetispeed(&t, B115200);
    ::cfsetospeed(&t, B115200);
    if (::tcsetattr(fd.get(), TCSANOW, &t) != 0) {
      int e = errno;
      throw DeviceError(fmt::format("{}: tcsetattr on {}: {}", endpoint_, path_, errno_text(e)));
    }
    fd_ = std::move(fd);
  }

 private:
  std::string path_;
};

// A TCP client, for lab terminal servers that expose a serial line on a port.
class TcpStream final : public FdStream {
 public:
  TcpStream(std::string endpoint, std::string host, int port, double connect_timeout_s)
      : FdStream(std::move(endpoint)), host_(std::move(host)), port_(port), connect_timeout_s_(connect_timeout_s) {}

  void open() override {
    close();
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    addrinfo* res = nullptr;
    std::string port = std::to_string(port_);
    if (int rc = ::getaddrinfo(host_.c_str(), port.c_str(), &hints, &res); rc != 0)
      throw DeviceError(fmt::format("{}: cannot resolve host '{}': {}", endpoint_, host_, ::gai_strerror(rc)));
    std::string last = "no address";
    for (addrinfo* a = res; a; a = a->ai_next) {
      UniqueFd fd(::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol));
      if (!fd) {
        last = fmt::format("socket: {}", errno_text(errno));
        continue;
      }
      int rc = ::connect(fd.get(), a->ai_addr, a->ai_addrlen);
      int e = rc == 0 ? 0 : errno;
      if (rc != 0 && e == EINPROGRESS) {
        pollfd p{fd.get(), POLLOUT, 0};
        int pr;
        do pr = ::poll(&p, 1, to_ms(connect_timeout_s_));
        while (pr < 0 && errno == EINTR);
        if (pr == 0) {
          e = ETIMEDOUT;
        } else {
          socklen_t len = sizeof e;
          ::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &e, &len);
        }
      }
      if (e != 0) {
        last = fmt::format("connect: {}", errno_text(e));
        continue;
      }
      int one = 1;
      ::setsockopt(fd.get(), IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
      fd_ = std::move(fd);
      break;
    }
    ::freeaddrinfo(res);
    if (!fd_) throw DeviceError(fmt::format("{}: cannot connect to {}:{}: {}", endpoint_, host_, port_, last));
  }

 protected:
  ssize_t recv_some(uint8_t* buf, std::size_t n) override { return ::recv(fd_.get(), buf, n, 0); }
  // MSG_NOSIGNAL: a peer that went away must give EPIPE, not kill the process with SIGPIPE.
  ssize_t send_some(const uint8_t* data, std::size_t n) override { return ::send(fd_.get(), data, n, MSG_NOSIGNAL); }

 private:
  std::string host_;
  int port_;
  double connect_timeout_s_;
};

std::string sp_text(sp_return rc) {
  if (rc == SP_ERR_FAIL) {
    char* msg = sp_last_error_message();
    std::string s = msg ? msg : "failed";
    sp_free_error_message(msg);
    while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
    return fmt::format("{} (errno {})", s, sp_last_error_code());
  }
  switch (rc) {
    case SP_ERR_ARG: return "invalid argument (SP_ERR_ARG)";
    case SP_ERR_MEM: return "out of memory (SP_ERR_MEM)";
    case SP_ERR_SUPP: return "not supported (SP_ERR_SUPP)";
    default: return fmt::format("libserialport error {}", static_cast<int>(rc));
  }
}

struct PortDeleter {
  void operator()(sp_port* p) const {
    sp_close(p);  // harmless on a port that is not open
    sp_free_port(p);
  }
};
using PortPtr = std::unique_ptr<sp_port, PortDeleter>;

// Unix 98 pseudo-terminal slaves: /dev/pts/N, character devices of majors 136..143.
bool is_pseudo_terminal(const std::string& device) {
  if (device.rfind("/dev/pts/", 0) == 0) return true;
  struct stat st {};
  if (::stat(device.c_str(), &st) != 0 || !S_ISCHR(st.st_mode)) return false;
  return major(st.st_rdev) >= 136 && major(st.st_rdev) <= 143;
}

// A real serial port through libserialport: 8N1, no flow control.
class SerialPortStream final : public ByteStream {
 public:
  SerialPortStream(std::string endpoint, std::string path, int baud)
      : endpoint_(std::move(endpoint)), path_(std::move(path)), baud_(baud) {}
  ~SerialPortStream() override { SerialPortStream::close(); }

  void open() override {
    close();
    // Ports are often named by links (udev's /dev/serial/by-id/..., an emulator's --serial-link);
    // libserialport looks the name up in /sys and wants the device itself.
    std::error_code ec;
    const std::filesystem::path real = std::filesystem::canonical(path_, ec);
    const std::string device = ec ? path_ : real.string();
    const std::string shown = device == path_ ? path_ : fmt::format("{} (-> {})", path_, device);
    if (is_pseudo_terminal(device)) {
      throw DeviceError(fmt::format("{}: {} is a pseudo-terminal, which libserialport cannot open: use the endpoint "
                                    "pty:{}", endpoint_, shown, path_));
    }
    sp_port* raw = nullptr;
    if (sp_return rc = sp_get_port_by_name(device.c_str(), &raw); rc != SP_OK) {
      throw DeviceError(fmt::format("{}: no serial port {}: {}", endpoint_, shown, sp_text(rc)));
    }
    PortPtr port(raw);
    if (sp_return rc = sp_open(port.get(), SP_MODE_READ_WRITE); rc != SP_OK)
      throw DeviceError(fmt::format("{}: cannot open {}: {}", endpoint_, path_, sp_text(rc)));
    auto check = [&](sp_return rc, const char* what) {
      if (rc != SP_OK) throw DeviceError(fmt::format("{}: {} on {}: {}", endpoint_, what, path_, sp_text(rc)));
    };
    check(sp_set_baudrate(port.get(), baud_), "setting the baud rate");
    check(sp_set_bits(port.get(), 8), "setting 8 data bits");
    check(sp_set_parity(port.get(), SP_PARITY_NONE), "setting no parity");
    check(sp_set_stopbits(port.get(), 1), "setting 1 stop bit");
    check(sp_set_flowcontrol(port.get(), SP_FLOWCONTROL_NONE), "disabling flow control");
    port_ = std::move(port);
  }
  void close() override { port_.reset(); }
  bool is_open() const override { return port_ != nullptr; }
  const std::string& endpoint() const override { return endpoint_; }

  std::size_t read(uint8_t* buf, std::size_t n, double timeout_s) override {
    if (!port_) throw DeviceError(fmt::format("{}: read on a closed link", endpoint_));
    unsigned ms = static_cast<unsigned>(to_ms(timeout_s));
    sp_return rc = ms ? sp_blocking_read_next(port_.get(), buf, n, ms) : sp_nonblocking_read(port_.get(), buf, n);
    if (rc < 0)  // e.g. a USB adapter that was unplugged; the owner closes and reopens
      throw DeviceError(fmt::format("{}: read failed: {}; link lost", endpoint_, sp_text(rc)));
    return static_cast<std::size_t>(rc);
  }

  void write(const uint8_t* data, std::size_t n, double timeout_s) override {
    if (!port_) throw DeviceError(fmt::format("{}: write on a closed link", endpoint_));
    sp_return rc = sp_blocking_write(port_.get(), data, n, static_cast<unsigned>(std::max(1, to_ms(timeout_s))));
    if (rc < 0) throw DeviceError(fmt::format("{}: write failed: {}; link lost", endpoint_, sp_text(rc)));
    if (static_cast<std::size_t>(rc) != n)
      throw DeviceError(
          fmt::format("{}: write timed out after {} s with {} of {} bytes sent", endpoint_, timeout_s, rc, n));
  }

 private:
  std::string endpoint_, path_;
  int baud_;
  PortPtr port_;
};

}  // namespace

std::unique_ptr<ByteStream> make_byte_stream(const std::string& endpoint, double connect_timeout_s) {
  Endpoint ep = parse_endpoint(endpoint);
  switch (ep.kind) {
    case Endpoint::Kind::serial: return std::make_unique<SerialPortStream>(endpoint, ep.path, ep.baud);
    case Endpoint::Kind::pty: return std::make_unique<PtyStream>(endpoint, ep.path);
    case Endpoint::Kind::tcp: return std::make_unique<TcpStream>(endpoint, ep.host, ep.port, connect_timeout_s);
    default:
      throw EndpointError(fmt::format("bad byte-stream endpoint '{}': {} is not a byte stream, expected "
                                      "serial:DEVICE[:BAUD], pty:PATH or tcp:HOST:PORT",
                                      endpoint, to_string(ep.kind)));
  }
}

std::vector<SerialPortInfo> list_serial_ports() {
  sp_port** list = nullptr;
  if (sp_return rc = sp_list_ports(&list); rc != SP_OK)
    throw DeviceError(fmt::format("listing serial ports: {}", sp_text(rc)));
  std::vector<SerialPortInfo> out;
  for (sp_port** p = list; *p; ++p) {
    SerialPortInfo info;
    const char* s = sp_get_port_name(*p);
    info.name = s ? s : "";
    char* d = sp_get_port_description(*p);
    info.description = d ? d : "";
    switch (sp_get_port_transport(*p)) {
      case SP_TRANSPORT_USB: {
        info.transport = "usb";
        sp_get_port_usb_vid_pid(*p, &info.usb_vid, &info.usb_pid);
        char* sn = sp_get_port_usb_serial(*p);
        info.usb_serial = sn ? sn : "";
        break;
      }
      case SP_TRANSPORT_BLUETOOTH: info.transport = "bluetooth"; break;
      default: info.transport = "native"; break;
    }
    out.push_back(std::move(info));
  }
  sp_free_port_list(list);
  return out;
}

}  // namespace fpss
