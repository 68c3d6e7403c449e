// SIGINT and SIGTERM abort a run to its safe state, SIGUSR1 toggles pause: for as long as a scope holds them.
#pragma once
#include <signal.h>

#include "procedures/engine.h"

namespace fpss {

// Installs the run's handlers on construction (without SA_RESTART, so a blocking wait returns and
// the engine looks at the flags) and restores the previous ones on destruction. One at a time.
class SignalScope {
 public:
  explicit SignalScope(RunControl& control);
  ~SignalScope();
  SignalScope(const SignalScope&) = delete;
  SignalScope& operator=(const SignalScope&) = delete;

 private:
  struct sigaction old_int_ {}, old_term_ {}, old_usr1_ {};
};

}  // namespace fpss
