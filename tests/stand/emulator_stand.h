// A running `fpss-stand emulate` (its own process, as an operator starts it) and the shipped
// procedures/emulator_stand.yaml pointed at it: a real stand on the wire for tests of `--stand`.
#pragma once
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "stand/contract/emulator_contract.h"
#include "tests/support/test_support.h"

namespace fpss::test {

inline std::string shipped_procedure(const char* name) { return (source_dir() / "procedures" / name).string(); }

inline void replace_text(std::string& text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
}

// emulator_stand.yaml as shipped, but for the endpoints: its gimbal port and sensor link are fixed
// names (1502, /tmp/fpss-sensor) and tests run side by side, so this emulator picks a free port
// and a link in the test's folder; every other setting (axes, clock, speed, limits) is the file's.
struct EmulatorStand {
  explicit EmulatorStand(const TempDir& tmp)
      : emu(start_emulate({"--modbus-port", "0", "--serial-link", (tmp / "fpss-sensor").string()}, tmp / "emulate.err")) {
    EmulatorReadyLines ready;
    while (!ready.ready) {
      const auto line = emu.line(60);
      if (!line) {
        ADD_FAILURE() << read_file(tmp / "emulate.err");
        return;
      }
      ready.take_line(*line);
    }
    std::string stand = read_file(shipped_procedure("emulator_stand.yaml"));
    replace_text(stand, "modbus-tcp:127.0.0.1:1502", ready.gimbal);
    replace_text(stand, "pty:/tmp/fpss-sensor", "pty:" + (tmp / "fpss-sensor").string());
    stand_file = tmp.write("stand.yaml", stand);
  }
  Child emu;
  std::filesystem::path stand_file;  // empty when the emulator did not come up
};

}  // namespace fpss::test
