// Endpoint syntax: every documented form, and clear errors for the rest.
#include "drivers/endpoints.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "drivers/modbus_gimbal.h"
#include "drivers/serial_sensor.h"

using testing::HasSubstr;
namespace fpss {
namespace {

// Every documented form and all it parses to: a network kind leaves the serial fields at their
// defaults and a serial kind the network ones.
TEST(Endpoints, EveryDocumentedFormGivesItsFields) {
  using K = Endpoint::Kind;
  struct Case {
    const char* text;
    K kind;
    const char* host;
    int port;
    const char* path;
    int baud;
    char parity;
    int data_bits, stop_bits;
  } cases[] = {
      {"modbus-tcp:127.0.0.1:1502", K::modbus_tcp, "127.0.0.1", 1502, "", 115200, 'N', 8, 1},
      {"modbus-tcp:[::1]:502", K::modbus_tcp, "::1", 502, "", 115200, 'N', 8, 1},
      {"modbus-tcp:gimbal.lab:1502", K::modbus_tcp, "gimbal.lab", 1502, "", 115200, 'N', 8, 1},
      {"modbus-rtu:/dev/ttyUSB1", K::modbus_rtu, "", 0, "/dev/ttyUSB1", 115200, 'N', 8, 1},
      {"modbus-rtu:/dev/ttyUSB1:19200", K::modbus_rtu, "", 0, "/dev/ttyUSB1", 19200, 'N', 8, 1},
      {"modbus-rtu:/dev/ttyUSB1:9600:8E1", K::modbus_rtu, "", 0, "/dev/ttyUSB1", 9600, 'E', 8, 1},
      {"serial:/dev/ttyUSB0", K::serial, "", 0, "/dev/ttyUSB0", 115200, 'N', 8, 1},
      {"serial:/dev/ttyUSB0:57600", K::serial, "", 0, "/dev/ttyUSB0", 57600, 'N', 8, 1},
      {"pty:/dev/pts/7", K::pty, "", 0, "/dev/pts/7", 115200, 'N', 8, 1},
      // a link path may contain colons
      {"pty:/tmp/run:3/sensor", K::pty, "", 0, "/tmp/run:3/sensor", 115200, 'N', 8, 1},
      {"tcp:terminal-server:4001", K::tcp, "terminal-server", 4001, "", 115200, 'N', 8, 1},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.text);
    const Endpoint e = parse_endpoint(c.text);
    EXPECT_EQ(e.kind, c.kind);
    EXPECT_EQ(e.host, c.host);
    EXPECT_EQ(e.port, c.port);
    EXPECT_EQ(e.path, c.path);
    EXPECT_EQ(e.baud, c.baud);
    EXPECT_EQ(e.parity, c.parity);
    EXPECT_EQ(e.data_bits, c.data_bits);
    EXPECT_EQ(e.stop_bits, c.stop_bits);
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
