// What every device the stand drives has: a link that connect() opens, and one owner.
#pragma once

namespace fpss {

// Constructors touch no hardware; connect() does (and throws DeviceError, drivers/gimbal.h, when it
// cannot). Not copyable: a device owns its C handles and descriptors, and two copies would close
// them twice.
class Device {
 public:
  Device() = default;
  Device(const Device&) = delete;
  Device& operator=(const Device&) = delete;
  virtual ~Device() = default;

  virtual void connect() = 0;
  virtual void disconnect() = 0;
  virtual bool connected() const = 0;
};

}  // namespace fpss
