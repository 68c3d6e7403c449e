// The FPSS electronics as the stand sees them: an interface; SerialSensor is the real driver.
#pragma once
#include <cstdint>
#include <optional>
#include <string>

#include "drivers/device.h"

namespace fpss {

// Sample status bits (ICD, sample frame).
enum SensorStatusBit : uint8_t { kSunPresent = 1u << 0, kAlphaValid = 1u << 1, kBetaValid = 1u << 2, kSaturated = 1u << 3 };

struct SensorSample {
  uint16_t seq = 0;
  uint32_t sensor_time_us = 0;  // as sent: free-running, wraps
  double sensor_time_s = 0;     // unwrapped sensor time since the first frame's clock zero
  int16_t counts_alpha = 0, counts_beta = 0;
  uint8_t status = 0;
  double host_time_s = 0;  // host steady clock at receipt

  // The rule for a valid sample (docs/icd.md, "Sensor to host"); fixtures/icd.h states the same
  // for the emulator and the in-process recorder, which may not include drivers' code.
  bool valid() const {
    return (status & kSunPresent) && (status & kAlphaValid) && (status & kBetaValid) && !(status & kSaturated);
  }
};

struct SensorStats {
  uint64_t frames = 0;        // good sample frames
  uint64_t replies = 0;       // good reply frames
  uint64_t crc_errors = 0;    // frames dropped for a bad CRC
  uint64_t garbage_bytes = 0; // bytes skipped while resynchronising
  uint64_t seq_gaps = 0;      // discontinuities in seq
  uint64_t frames_lost = 0;   // frames missing by seq
  uint64_t samples_dropped = 0;  // queued samples dropped because nobody read them in time
  uint64_t reconnects = 0;       // successful reopenings of the link after it dropped
};

class Sensor : public Device {
 public:
  virtual std::string identify() = 0;  // "FPSS,SN=<serial>,FW=<version>"
  virtual void set_rate(int hz) = 0;   // 1..200
  virtual void start() = 0;
  virtual void stop() = 0;
  virtual double temperature_c() = 0;
  // The next sample frame, or nullopt when none arrives within timeout_s (wall seconds).
  virtual std::optional<SensorSample> next_sample(double timeout_s) = 0;
  // Drops buffered samples (after a move, so old frames are not taken for new ones).
  virtual void flush() = 0;
  virtual SensorStats stats() const = 0;
};

}  // namespace fpss
