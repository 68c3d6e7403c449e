// Emulator options for tests: ephemeral Modbus port, the bench clock running at `speed`.
#pragma once
#include "fixtures/emulator.h"

namespace fpss::test {

inline EmulatorOptions running_emulator_options(double speed) {
  EmulatorOptions o;
  o.modbus_port = 0;
  o.speed = speed;
  return o;
}

}  // namespace fpss::test
