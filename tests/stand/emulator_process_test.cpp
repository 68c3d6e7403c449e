// The emulator launcher: `fpss-stand emulate` as a child process, its ready lines read by the contract.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include "stand/session/emulator_process.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

using test::TempDir;

TEST(EmulatorProcess, ReportsBothEndpointsAndWhyItCannotStart) {
  TempDir tmp("engine-emu");
  EmulatorLaunch l;
  l.exe = test::stand_binary();
  l.log = tmp / "emu.log";
  EmulatorProcess emu(l);
  EXPECT_FALSE(emu.running());
  emu.start();
  EXPECT_TRUE(emu.running());
  EXPECT_EQ(emu.gimbal_endpoint().rfind("modbus-tcp:127.0.0.1:", 0), 0u) << emu.gimbal_endpoint();
  EXPECT_EQ(emu.sensor_endpoint().rfind("pty:/dev/pts/", 0), 0u) << emu.sensor_endpoint();
  const int status = emu.stop();
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;  // SIGTERM: a clean exit 0
  EXPECT_FALSE(emu.running());
  // A bench that cannot start says why.
  EmulatorLaunch bad = l;
  bad.args = {"--bench", (tmp / "missing.yaml").string()};
  EmulatorProcess emu2(bad);
  try {
    emu2.start();
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("exited before it was ready"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace fpss
