// Byte streams over a real pty pair and a real loopback TCP socket; libserialport listing and errors.
#include "drivers/byte_stream.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <random>

#include "drivers/endpoints.h"
#include "test_util.h"

using testing::HasSubstr;
namespace fpss {
namespace {

using test::error_of;

std::vector<uint8_t> read_exactly(ByteStream& s, std::size_t n) {
  std::vector<uint8_t> out;
  uint8_t buf[1024];
  EXPECT_TRUE(test::wait_until([&] {
    out.insert(out.end(), buf, buf + s.read(buf, std::min(sizeof buf, n - out.size()), 0.05));
    return out.size() >= n;
  })) << out.size() << " of " << n << " bytes came";
  return out;
}

std::vector<uint8_t> read_fd_exactly(int fd, std::size_t n) {
  std::vector<uint8_t> out(n);
  std::size_t got = 0;
  EXPECT_TRUE(test::wait_until([&] {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) > 0) {
      ssize_t r = ::read(fd, out.data() + got, n - got);
      if (r > 0) got += static_cast<std::size_t>(r);
    }
    return got >= n;
  })) << got << " of " << n << " bytes came";
  out.resize(got);
  return out;
}

std::vector<uint8_t> random_bytes(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<uint8_t> b(n);
  for (auto& x : b) x = static_cast<uint8_t>(rng());
  return b;
}

// `in` from the peer's end of the link to the stream, then `out` back: every byte arrives, in order.
void expect_both_ways(ByteStream& s, int peer, const std::vector<uint8_t>& in, const std::vector<uint8_t>& out) {
  std::thread writer([&] { test::write_all(peer, in.data(), in.size()); });
  EXPECT_EQ(read_exactly(s, in.size()), in);
  writer.join();
  s.write(out.data(), out.size());
  EXPECT_EQ(read_fd_exactly(peer, out.size()), out);
}


TEST(PtyStream, RawBytesBothWaysOverARealPty) {
  test::PtyPair pty;
  auto s = make_byte_stream("pty:" + pty.slave_path());
  EXPECT_FALSE(s->is_open());
  s->open();
  EXPECT_TRUE(s->is_open());
  // Every byte value, including \r \n ^C ^S ^Q and 0xFF, must pass untouched (raw mode).
  auto data = random_bytes(20000, 3);
  for (int v = 0; v < 256; ++v) data.push_back(static_cast<uint8_t>(v));
  expect_both_ways(*s, pty.master(), data, random_bytes(3000, 4));
}

TEST(PtyStream, ReadTimesOutWithZeroAndHangupIsAnError) {
  test::PtyPair pty;
  auto s = make_byte_stream("pty:" + pty.slave_path());
  s->open();
  uint8_t buf[16];
  EXPECT_EQ(s->read(buf, sizeof buf, 0.01), 0u);
  pty.close_master();
  const auto msg = test::error_within<DeviceError>([&] { s->read(buf, sizeof buf, 0.05); });
  EXPECT_TRUE(msg.has_value());
  EXPECT_THAT(msg.value_or(""), HasSubstr(pty.slave_path()));
  EXPECT_TRUE(s->is_open());  // the owner closes, never the stream behind its back
  s->close();
  EXPECT_FALSE(s->is_open());
  EXPECT_THROW(s->open(), DeviceError);  // the pty is gone with its master
}

TEST(TcpStream, BytesBothWaysOverLoopbackAndHangup) {
  test::TcpListener listener;
  auto s = make_byte_stream("tcp:127.0.0.1:" + std::to_string(listener.port()));
  s->open();
  int peer = listener.accept();
  ASSERT_GE(peer, 0);
  const auto back = random_bytes(5000, 6);
  expect_both_ways(*s, peer, random_bytes(100000, 5), back);

  ::close(peer);
  uint8_t buf[8];
  const auto msg = test::error_within<DeviceError>([&] { s->read(buf, sizeof buf, 0.05); });
  EXPECT_TRUE(msg.has_value());
  EXPECT_THAT(msg.value_or(""), HasSubstr("hung up"));
  // Writing into a dead socket is an error, not a SIGPIPE (the first write may still be accepted
  // by the kernel; the reset shows on a later one).
  EXPECT_TRUE(test::error_within<DeviceError>([&] { s->write(back.data(), back.size()); }).has_value());
  s->close();
  EXPECT_FALSE(s->is_open());
}

// What cannot be opened: a missing pty, a file that is not a terminal, a port that refuses, a host
// that does not exist. The message names it and why.
TEST(ByteStream, OpenErrorsNameTheDeviceAndTheReason) {
  test::RefusingPort refusing;
  const struct {
    std::string endpoint;
    std::vector<std::string> says;
  } cases[] = {
      {"pty:/dev/pts/does-not-exist", {"/dev/pts/does-not-exist", "errno 2"}},
      {"pty:/dev/null", {"not a terminal"}},
      {"tcp:127.0.0.1:" + std::to_string(refusing.port()), {"cannot connect", "errno 111"}},
      {"tcp:no-such-host.invalid:4000", {"no-such-host.invalid"}},
  };
  for (const auto& c : cases) {
    auto s = make_byte_stream(c.endpoint);
    const std::string msg = error_of([&] { s->open(); });
    for (const auto& part : c.says) EXPECT_THAT(msg, HasSubstr(part)) << c.endpoint;
  }
}

TEST(SerialStream, ListingWorksAndNeverShowsPtys) {
  test::PtyPair pty;
  std::vector<SerialPortInfo> ports;
  ASSERT_NO_THROW(ports = list_serial_ports());
  for (const auto& p : ports) {
    EXPECT_FALSE(p.name.empty());
    EXPECT_NE(p.name, pty.slave_path());
  }
}

TEST(SerialStream, MissingPortAndPtyGiveClearErrors) {
  auto s = make_byte_stream("serial:/dev/ttyFPSS-missing:9600");
  std::string msg = error_of([&] { s->open(); });
  EXPECT_THAT(msg, HasSubstr("/dev/ttyFPSS-missing"));
  EXPECT_FALSE(s->is_open());
  test::PtyPair pty;
  auto p = make_byte_stream("serial:" + pty.slave_path());
  EXPECT_THAT(error_of([&] { p->open(); }), HasSubstr("pty:"));
}

// An emulator's --serial-link (or any link) to a pty: the link is followed and the message says
// which device it is and that pty: is the endpoint for it, instead of libserialport's SP_ERR_ARG.
TEST(SerialStream, ALinkToAPtyIsFollowedAndNamesThePtyEndpoint) {
  test::PtyPair pty;
  test::TempDir tmp("serial-link");
  const auto link = tmp / "fpss-sensor";
  std::filesystem::create_symlink(pty.slave_path(), link);
  auto s = make_byte_stream("serial:" + link.string());
  const std::string msg = error_of([&] { s->open(); });
  EXPECT_THAT(msg, HasSubstr(link.string() + " (-> " + pty.slave_path() + ") is a pseudo-terminal"));
  EXPECT_THAT(msg, HasSubstr("use the endpoint pty:" + link.string()));
  EXPECT_THAT(msg, testing::Not(HasSubstr("SP_ERR_ARG")));
  // What the message says works.
  auto p = make_byte_stream("pty:" + link.string());
  ASSERT_NO_THROW(p->open());
  EXPECT_TRUE(p->is_open());
}

TEST(ByteStreamFactory, RefusesNonStreamAndBadEndpoints) {
  EXPECT_THROW(make_byte_stream("modbus-tcp:127.0.0.1:1502"), EndpointError);
  EXPECT_THROW(make_byte_stream("usb:/dev/ttyUSB0"), EndpointError);
  EXPECT_THROW(make_byte_stream("tcp:127.0.0.1"), EndpointError);
  EXPECT_THROW(make_byte_stream("serial:"), EndpointError);
}

}  // namespace
}  // namespace fpss
