#include "stand/session/signals.h"

namespace fpss {

namespace {

RunControl* g_control = nullptr;

extern "C" void on_signal(int sig) {
  if (!g_control) return;
  if (sig == SIGUSR1) {
    g_control->pause.store(!g_control->pause.load());
    return;
  }
  g_control->signal.store(sig);
  g_control->abort.store(true);
}

}  // namespace

SignalScope::SignalScope(RunControl& c) {
  g_control = &c;
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: a blocking wait returns and the engine looks at the flag
  ::sigaction(SIGINT, &sa, &old_int_);
  ::sigaction(SIGTERM, &sa, &old_term_);
  ::sigaction(SIGUSR1, &sa, &old_usr1_);
}

SignalScope::~SignalScope() {
  ::sigaction(SIGINT, &old_int_, nullptr);
  ::sigaction(SIGTERM, &old_term_, nullptr);
  ::sigaction(SIGUSR1, &old_usr1_, nullptr);
  g_control = nullptr;
}

}  // namespace fpss
