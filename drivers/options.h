// Options of the two device drivers: endpoint, soft limits, timeouts and the retry policy.
#pragma once
#include <cstddef>
#include <string>

#include "drivers/gimbal.h"

namespace fpss {

struct GimbalOptions {
  // modbus-tcp:HOST:PORT or modbus-rtu:DEVICE[:BAUD[:8N1|8E1|8O1|8N2]] (docs/icd.md).
  std::string endpoint = "modbus-tcp:127.0.0.1:1502";
  int unit_id = 1;
  SoftLimits limits{};
  double response_timeout_s = 0.5;  // one Modbus request/response (also the TCP connect timeout)
  // Further attempts after a timeout, a dropped link or a corrupt reply; each reconnects first.
  // Modbus exceptions are answers, not faults of the link: they are never retried (06 busy aside).
  int retries = 3;
  double backoff_s = 0.05;      // before the first retry; doubles each time ...
  double max_backoff_s = 1.0;   // ... up to this
  double poll_interval_s = 0.02;  // wait_in_position status polling
  // The gimbal has the scheduled move (docs/icd.md: holding 13..16 and command 6); a stand says so.
  bool timed_moves = false;
};

struct SensorOptions {
  // serial:DEVICE[:BAUD], pty:PATH or tcp:HOST:PORT (docs/icd.md).
  std::string endpoint;
  double command_timeout_s = 1.0;  // wait for the reply to one command line
  int command_retries = 2;         // further sends of a command whose reply timed out
  int reconnects = 3;              // reopen attempts after the link drops, then DeviceError
  double reconnect_backoff_s = 0.2;  // before the first reopen; doubles each time
  double connect_timeout_s = 2.0;    // opening a tcp: endpoint
  // Samples nobody has read yet; beyond this the oldest are dropped (SensorStats::samples_dropped).
  std::size_t max_queued_samples = 1u << 16;
  // A TEMP reply outside [min, max] degC is an invalid reading, never a value (docs/icd.md, TEMP).
  double temperature_min_c = -60.0;
  double temperature_max_c = 100.0;
};

}  // namespace fpss
