// Driver options for tests: short backoffs, and timeouts generous enough that a loaded machine
// never causes a retry or a timeout the test does not provoke on purpose (tests about timeouts
// pass shorter ones).
#pragma once
#include <string>

#include "drivers/options.h"

namespace fpss::e2e {

inline GimbalOptions gimbal_options(const std::string& endpoint, double response_timeout_s = 5.0) {
  return {.endpoint = endpoint, .response_timeout_s = response_timeout_s, .retries = 2,
          .backoff_s = 0.01, .max_backoff_s = 0.05, .poll_interval_s = 0.005};
}

inline SensorOptions sensor_options(const std::string& endpoint, double command_timeout_s = 5.0) {
  return {.endpoint = endpoint, .command_timeout_s = command_timeout_s, .command_retries = 1,
          .reconnects = 2, .reconnect_backoff_s = 0.02};
}

}  // namespace fpss::e2e
