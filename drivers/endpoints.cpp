// Endpoint parsing and the driver factories.
#include "drivers/endpoints.h"

#include <fmt/format.h>

#include <charconv>
#include <string_view>

#include "drivers/modbus_gimbal.h"
#include "drivers/serial_sensor.h"

namespace fpss {
namespace {

constexpr const char* kSyntax =
    "expected modbus-tcp:HOST:PORT, modbus-rtu:DEVICE[:BAUD[:8N1|8E1|8O1|8N2]], serial:DEVICE[:BAUD], "
    "pty:PATH or tcp:HOST:PORT";

[[noreturn]] void fail(const std::string& text, const std::string& why) {
  throw EndpointError(fmt::format("bad endpoint '{}': {} ({})", text, why, kSyntax));
}

bool parse_int(std::string_view s, int& out) {
  if (s.empty()) return false;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && p == s.data() + s.size();
}

bool all_digits(std::string_view s) {
  if (s.empty()) return false;
  for (char c : s)
    if (c < '0' || c > '9') return false;
  return true;
}

// HOST:PORT; the port is after the last colon so that [v6]:port style hosts keep theirs.
void parse_host_port(const std::string& text, std::string_view rest, Endpoint& ep) {
  auto colon = rest.rfind(':');
  if (colon == std::string_view::npos) fail(text, "missing ':PORT'");
  std::string_view host = rest.substr(0, colon), port = rest.substr(colon + 1);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  if (host.empty()) fail(text, "empty host");
  if (!parse_int(port, ep.port) || ep.port < 1 || ep.port > 65535)
    fail(text, fmt::format("port '{}' is not a number in 1..65535", port));
  ep.host = std::string(host);
}

void parse_baud(const std::string& text, std::string_view s, Endpoint& ep) {
  if (!parse_int(s, ep.baud) || ep.baud < 50 || ep.baud > 4000000)
    fail(text, fmt::format("baud rate '{}' is not a number in 50..4000000", s));
}

}  // namespace

const char* to_string(Endpoint::Kind kind) {
  switch (kind) {
    case Endpoint::Kind::modbus_tcp: return "modbus-tcp";
    case Endpoint::Kind::modbus_rtu: return "modbus-rtu";
    case Endpoint::Kind::serial: return "serial";
    case Endpoint::Kind::pty: return "pty";
    case Endpoint::Kind::tcp: return "tcp";
  }
  return "?";
}

Endpoint parse_endpoint(const std::string& text) {
  Endpoint ep;
  ep.text = text;
  auto colon = text.find(':');
  if (colon == std::string::npos) fail(text, "no scheme");
  std::string_view scheme = std::string_view(text).substr(0, colon);
  std::string_view rest = std::string_view(text).substr(colon + 1);
  if (rest.empty()) fail(text, "nothing after the scheme");

  if (scheme == "modbus-tcp" || scheme == "tcp") {
    ep.kind = scheme == "tcp" ? Endpoint::Kind::tcp : Endpoint::Kind::modbus_tcp;
    parse_host_port(text, rest, ep);
  } else if (scheme == "pty") {
    ep.kind = Endpoint::Kind::pty;
    ep.path = std::string(rest);  // a pty is always 115200 8N1 raw; the whole rest is the path
  } else if (scheme == "serial") {
    ep.kind = Endpoint::Kind::serial;
    auto c = rest.rfind(':');
    if (c != std::string_view::npos && all_digits(rest.substr(c + 1))) {
      parse_baud(text, rest.substr(c + 1), ep);
      rest = rest.substr(0, c);
    }
    ep.path = std::string(rest);
  } else if (scheme == "modbus-rtu") {
    ep.kind = Endpoint::Kind::modbus_rtu;
    // DEVICE[:BAUD[:FRAMING]]: peel FRAMING, then BAUD, from the right.
    auto c = rest.rfind(':');
    if (c != std::string_view::npos) {
      std::string_view last = rest.substr(c + 1);
      if (last.size() == 3 && (last[0] == '7' || last[0] == '8') &&
          (last[1] == 'N' || last[1] == 'E' || last[1] == 'O') && (last[2] == '1' || last[2] == '2')) {
        ep.data_bits = last[0] - '0';
        ep.parity = last[1];
        ep.stop_bits = last[2] - '0';
        rest = rest.substr(0, c);
        c = rest.rfind(':');
        if (c == std::string_view::npos || !all_digits(rest.substr(c + 1)))
          fail(text, "framing given without a baud rate");
      }
    }
    if (c != std::string_view::npos && all_digits(rest.substr(c + 1))) {
      parse_baud(text, rest.substr(c + 1), ep);
      rest = rest.substr(0, c);
    }
    ep.path = std::string(rest);
  } else {
    fail(text, fmt::format("unknown scheme '{}'", scheme));
  }
  if ((ep.kind == Endpoint::Kind::serial || ep.kind == Endpoint::Kind::pty ||
       ep.kind == Endpoint::Kind::modbus_rtu) && ep.path.empty())
    fail(text, "empty device path");
  return ep;
}

std::unique_ptr<Gimbal> make_gimbal(const GimbalOptions& options) {
  Endpoint ep = parse_endpoint(options.endpoint);
  if (ep.kind != Endpoint::Kind::modbus_tcp && ep.kind != Endpoint::Kind::modbus_rtu)
    throw EndpointError(fmt::format("bad gimbal endpoint '{}': a gimbal speaks Modbus, expected "
                                    "modbus-tcp:HOST:PORT or modbus-rtu:DEVICE[:BAUD]",
                                    options.endpoint));
  return std::make_unique<ModbusGimbal>(options);
}

std::unique_ptr<Sensor> make_sensor(const SensorOptions& options) {
  Endpoint ep = parse_endpoint(options.endpoint);
  if (ep.kind != Endpoint::Kind::serial && ep.kind != Endpoint::Kind::pty && ep.kind != Endpoint::Kind::tcp)
    throw EndpointError(fmt::format("bad sensor endpoint '{}': expected serial:DEVICE[:BAUD], pty:PATH or tcp:HOST:PORT",
                                    options.endpoint));
  return std::make_unique<SerialSensor>(options);
}

}  // namespace fpss
