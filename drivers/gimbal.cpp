// Names of the gimbal fault codes (ICD input register 9), for messages and logs.
#include "drivers/gimbal.h"

namespace fpss {

const char* to_string(GimbalFault f) {
  switch (f) {
    case GimbalFault::none: return "none";
    case GimbalFault::following_error: return "following_error";
    case GimbalFault::limit: return "limit";
    case GimbalFault::estop: return "estop";
    case GimbalFault::watchdog: return "watchdog";
    case GimbalFault::bad_command: return "bad_command";
  }
  return "unknown";
}

}  // namespace fpss
