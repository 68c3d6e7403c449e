// Endpoint syntax: every documented form, and clear errors for the rest.
#include "drivers/endpoints.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tuple>

#include "drivers/modbus_gimbal.h"
#include "drivers/serial_sensor.h"

using testing::HasSubstr;
namespace fpss {
namespace {

// What a parsed endpoint says, field by field, for comparing one with another.
auto fields(const Endpoint& e) {
  return std::tie(e.kind, e.host, e.port, e.path, e.baud, e.parity, e.data_bits, e.stop_bits);
}

// An endpoint on the network; the serial fields keep their defaults.
Endpoint at_host(Endpoint::Kind kind, const std::string& host, int port) {
  Endpoint e;
  e.kind = kind;
  e.host = host;
  e.port = port;
  return e;
}

// An endpoint on a device path, 8 data bits and 1 stop bit; the network fields keep their defaults.
Endpoint at_path(Endpoint::Kind kind, const std::string& path, int baud = 115200, char parity = 'N') {
  Endpoint e;
  e.kind = kind;
  e.path = path;
  e.baud = baud;
  e.parity = parity;
  return e;
}

// Every documented form and all it parses to.
TEST(Endpoints, EveryDocumentedFormGivesItsFields) {
  using K = Endpoint::Kind;
  const struct {
    const char* text;
    Endpoint expected;
  } cases[] = {
      {"modbus-tcp:127.0.0.1:1502", at_host(K::modbus_tcp, "127.0.0.1", 1502)},
      {"modbus-tcp:[::1]:502", at_host(K::modbus_tcp, "::1", 502)},
      {"modbus-tcp:gimbal.lab:1502", at_host(K::modbus_tcp, "gimbal.lab", 1502)},
      {"modbus-rtu:/dev/ttyUSB1", at_path(K::modbus_rtu, "/dev/ttyUSB1", 115200, 'N')},
      {"modbus-rtu:/dev/ttyUSB1:19200", at_path(K::modbus_rtu, "/dev/ttyUSB1", 19200)},
      {"modbus-rtu:/dev/ttyUSB1:9600:8E1", at_path(K::modbus_rtu, "/dev/ttyUSB1", 9600, 'E')},
      {"serial:/dev/ttyUSB0", at_path(K::serial, "/dev/ttyUSB0", 115200)},
      {"serial:/dev/ttyUSB0:57600", at_path(K::serial, "/dev/ttyUSB0", 57600)},
      {"pty:/dev/pts/7", at_path(K::pty, "/dev/pts/7")},
      {"pty:/tmp/run:3/sensor", at_path(K::pty, "/tmp/run:3/sensor")},  // a link path may contain colons
      {"tcp:terminal-server:4001", at_host(K::tcp, "terminal-server", 4001)},
  };
  for (const auto& c : cases) {
    const Endpoint e = parse_endpoint(c.text);
    EXPECT_EQ(fields(e), fields(c.expected)) << c.text;
    EXPECT_EQ(e.text, c.text);
  }
  EXPECT_THROW(parse_endpoint("modbus-rtu:/dev/ttyUSB1:8E1"), EndpointError);  // framing needs the baud before it
}

TEST(Endpoints, BadStringsNameTheStringAndTheReason) {
  struct Case {
    const char* text;
    const char* why;
  } cases[] = {
      {"", "no scheme"},
      {"/dev/ttyUSB0", "no scheme"},
      {"usb:/dev/ttyUSB0", "unknown scheme 'usb'"},
      {"tcp:", "nothing after the scheme"},
      {"tcp:localhost", "missing ':PORT'"},
      {"tcp:localhost:http", "port 'http'"},
      {"tcp:localhost:0", "port '0'"},
      {"tcp:localhost:70000", "port '70000'"},
      {"modbus-tcp::1502", "empty host"},
      {"serial::9600", "empty device path"},
      {"serial:/dev/ttyS0:12", "baud rate '12'"},
  };
  for (const auto& c : cases) {
    try {
      parse_endpoint(c.text);
      ADD_FAILURE() << "accepted '" << c.text << "'";
    } catch (const EndpointError& e) {
      EXPECT_THAT(e.what(), HasSubstr(std::string("'") + c.text + "'"));
      EXPECT_THAT(e.what(), HasSubstr(c.why)) << c.text;
      EXPECT_THAT(e.what(), HasSubstr("expected"));
    }
  }
}

TEST(Endpoints, FactoriesBuildTheRightDriversWithoutTouchingHardware) {
  GimbalOptions g;
  g.endpoint = "modbus-rtu:/dev/ttyFPSS-none:115200";
  auto gimbal = make_gimbal(g);  // nothing opened yet, so a missing device is fine here
  EXPECT_NE(dynamic_cast<ModbusGimbal*>(gimbal.get()), nullptr);
  EXPECT_FALSE(gimbal->connected());
  SensorOptions s;
  s.endpoint = "serial:/dev/ttyFPSS-none";
  auto sensor = make_sensor(s);
  EXPECT_NE(dynamic_cast<SerialSensor*>(sensor.get()), nullptr);
  EXPECT_FALSE(sensor->connected());
  EXPECT_THROW(sensor->connect(), DeviceError);
  s.endpoint = "modbus-tcp:127.0.0.1:1502";
  EXPECT_THROW(make_sensor(s), EndpointError);
  g.endpoint = "tcp:127.0.0.1:1502";
  EXPECT_THROW(make_gimbal(g), EndpointError);
}

}  // namespace
}  // namespace fpss
