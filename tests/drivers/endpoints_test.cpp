// Endpoint syntax: every documented form, and clear errors for the rest.
#include "drivers/endpoints.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "drivers/modbus_gimbal.h"
#include "drivers/serial_sensor.h"

using testing::HasSubstr;
namespace fpss {
namespace {

TEST(Endpoints, ModbusTcp) {
  Endpoint e = parse_endpoint("modbus-tcp:127.0.0.1:1502");
  EXPECT_EQ(e.kind, Endpoint::Kind::modbus_tcp);
  EXPECT_EQ(e.host, "127.0.0.1");
  EXPECT_EQ(e.port, 1502);
  e = parse_endpoint("modbus-tcp:[::1]:502");
  EXPECT_EQ(e.host, "::1");
  EXPECT_EQ(e.port, 502);
  e = parse_endpoint("modbus-tcp:gimbal.lab:1502");
  EXPECT_EQ(e.host, "gimbal.lab");
}

TEST(Endpoints, ModbusRtuWithOptionalBaudAndFraming) {
  Endpoint e = parse_endpoint("modbus-rtu:/dev/ttyUSB1");
  EXPECT_EQ(e.kind, Endpoint::Kind::modbus_rtu);
  EXPECT_EQ(e.path, "/dev/ttyUSB1");
  EXPECT_EQ(e.baud, 115200);
  EXPECT_EQ(e.parity, 'N');
  e = parse_endpoint("modbus-rtu:/dev/ttyUSB1:19200");
  EXPECT_EQ(e.baud, 19200);
  e = parse_endpoint("modbus-rtu:/dev/ttyUSB1:9600:8E1");
  EXPECT_EQ(e.baud, 9600);
  EXPECT_EQ(e.parity, 'E');
  EXPECT_EQ(e.stop_bits, 1);
  EXPECT_EQ(e.path, "/dev/ttyUSB1");
  EXPECT_THROW(parse_endpoint("modbus-rtu:/dev/ttyUSB1:8E1"), EndpointError);
}

TEST(Endpoints, SerialPtyTcp) {
  Endpoint e = parse_endpoint("serial:/dev/ttyUSB0");
  EXPECT_EQ(e.kind, Endpoint::Kind::serial);
  EXPECT_EQ(e.path, "/dev/ttyUSB0");
  EXPECT_EQ(e.baud, 115200);
  e = parse_endpoint("serial:/dev/ttyUSB0:57600");
  EXPECT_EQ(e.baud, 57600);
  EXPECT_EQ(e.path, "/dev/ttyUSB0");
  e = parse_endpoint("pty:/dev/pts/7");
  EXPECT_EQ(e.kind, Endpoint::Kind::pty);
  EXPECT_EQ(e.path, "/dev/pts/7");
  e = parse_endpoint("pty:/tmp/run:3/sensor");  // a link path may contain colons
  EXPECT_EQ(e.path, "/tmp/run:3/sensor");
  e = parse_endpoint("tcp:terminal-server:4001");
  EXPECT_EQ(e.kind, Endpoint::Kind::tcp);
  EXPECT_EQ(e.host, "terminal-server");
  EXPECT_EQ(e.port, 4001);
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
