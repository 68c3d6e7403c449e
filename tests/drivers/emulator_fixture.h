// Shared set-up of the driver-against-emulator tests: an in-process emulated bench on ephemeral ports, driver options.
#pragma once
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>

#include "calib/coefficients.h"
#include "drivers/endpoints.h"
#include "drivers/modbus_gimbal.h"
#include "drivers/serial_sensor.h"
#include "fixtures/emulator.h"
#include "test_util.h"
#include "tests/drivers/driver_options.h"
#include "tests/support/emulator_options.h"

namespace fpss::e2e {

// Emulator options for a test: ephemeral Modbus port, a bench clock fast enough that moves of
// a few hundred arcsec take a few wall milliseconds.
inline EmulatorOptions emulator_options(double speed = 20.0) {
  return test::running_emulator_options(speed);
}

// What the emulator's gimbal holds in its target registers (ground truth, not over the wire).
struct Targets {
  double pitch_arcsec, yaw_arcsec;
  bool operator==(const Targets&) const = default;
};
inline Targets bench_targets(Emulator& emu) {
  return emu.with_bench([](Bench& b) { return Targets{b.target_pitch_arcsec(), b.target_yaw_arcsec()}; });
}
inline GimbalReadout bench_gimbal(Emulator& emu) {
  return emu.with_bench([](Bench& b) { return b.gimbal_noiseless(); });
}

// Manual bench clock: advance in small steps, polling through the driver, until the gimbal is
// in position (each poll is a request, so the watchdog is fed as a polling host would feed it).
inline GimbalState settle_manual(Emulator& emu, ModbusGimbal& g, double step_s = 0.1, int max_steps = 600) {
  GimbalState s;
  for (int i = 0; i < max_steps; ++i) {
    emu.advance_by(step_s);
    s = g.read_state();
    if (s.has(kInPosition) && !s.has(kMoving)) return s;
  }
  ADD_FAILURE() << "gimbal not in position after " << max_steps * step_s << " bench s";
  return s;
}

// How far one sample may invert from the true angle: half a count of rounding plus five sigma of
// the bench's count noise, at the local slope of the transfer function.
inline double tolerance_arcsec(const AxisModel& m, double counts, double count_noise) {
  return std::abs(rad_to_arcsec(m.slope_rad_per_count(counts))) * (0.5 + 5.0 * count_noise);
}

}  // namespace fpss::e2e
