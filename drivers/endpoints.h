// Endpoint strings -> drivers: the one place a configured endpoint becomes a Gimbal or a Sensor.
#pragma once
#include <memory>
#include <string>

#include "drivers/gimbal.h"
#include "drivers/options.h"
#include "drivers/sensor.h"

namespace fpss {

// A malformed or unknown endpoint string: bad input (the command line maps it to exit 2).
struct EndpointError : LimitError {
  using LimitError::LimitError;
};

// One parsed endpoint. Network kinds fill host/port, serial kinds fill path/baud/framing.
struct Endpoint {
  enum class Kind { modbus_tcp, modbus_rtu, serial, pty, tcp };
  Kind kind = Kind::tcp;
  std::string host;
  int port = 0;
  std::string path;
  int baud = 115200;
  char parity = 'N';  // modbus-rtu only: N, E or O
  int data_bits = 8;
  int stop_bits = 1;
  std::string text;  // as given, for messages
};

// Throws EndpointError naming the string and the expected syntax.
Endpoint parse_endpoint(const std::string& text);
const char* to_string(Endpoint::Kind kind);

// modbus-tcp:HOST:PORT, modbus-rtu:DEVICE[:BAUD[:FRAMING]] -> ModbusGimbal (not yet connected).
std::unique_ptr<Gimbal> make_gimbal(const GimbalOptions& options);
// serial:DEVICE[:BAUD], pty:PATH, tcp:HOST:PORT -> SerialSensor (not yet connected).
std::unique_ptr<Sensor> make_sensor(const SensorOptions& options);

}  // namespace fpss
