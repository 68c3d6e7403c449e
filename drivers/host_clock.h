// The host's steady clock in seconds: the drivers' receipt stamps (host_time_s) and deadlines.
#pragma once
#include <chrono>

namespace fpss {

using HostClock = std::chrono::steady_clock;

inline double host_now_s() { return std::chrono::duration<double>(HostClock::now().time_since_epoch()).count(); }

}  // namespace fpss
