// A byte pipe to the sensor electronics: libserialport for real ports, termios for ptys, TCP for terminal servers.
#pragma once
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "drivers/gimbal.h"  // DeviceError

namespace fpss {

class ByteStream {
 public:
  virtual ~ByteStream() = default;
  // Opens the link; throws DeviceError naming the endpoint and the errno / libserialport message.
  virtual void open() = 0;
  virtual void close() = 0;
  virtual bool is_open() const = 0;
  // Up to n bytes, waiting at most timeout_s for the first; 0 on timeout.
  // Throws DeviceError when the link is gone (hang-up, EOF, I/O error). A stream never closes
  // itself (another thread may be using it): the owner calls close(), then open() to reconnect.
  // One reader and one writer may work concurrently; open() and close() need both stopped.
  virtual std::size_t read(uint8_t* buf, std::size_t n, double timeout_s) = 0;
  // All n bytes or DeviceError (timeout_s bounds the whole write).
  virtual void write(const uint8_t* data, std::size_t n, double timeout_s = 1.0) = 0;
  virtual const std::string& endpoint() const = 0;
};

// serial:DEVICE[:BAUD] (libserialport, 8N1, no flow control), pty:PATH (termios raw 115200 8N1),
// tcp:HOST:PORT. Touches nothing until open(). Throws EndpointError for a bad or non-stream endpoint.
std::unique_ptr<ByteStream> make_byte_stream(const std::string& endpoint, double connect_timeout_s = 2.0);

struct SerialPortInfo {
  std::string name;         // /dev/ttyUSB0
  std::string description;  // as libserialport reports it
  std::string transport;    // native, usb, bluetooth
  int usb_vid = -1, usb_pid = -1;
  std::string usb_serial;
};
// The machine's serial ports as libserialport sees them (ptys never appear); throws DeviceError on failure.
std::vector<SerialPortInfo> list_serial_ports();

}  // namespace fpss
