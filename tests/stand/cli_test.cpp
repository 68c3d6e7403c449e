// The command line behaving like a user's other tools: out-of-range options exit 2 before anything
// starts, one flag name per idea (old spellings kept), progress only on a terminal, one error style,
// `runs` finding the catalogue the demo made, run ids by unique prefix and `latest`, `show` naming a
// diagnosis's verdict and cause. The real binary on the emulated bench.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/procedures/run_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using test::CommandResult;
using testing::HasSubstr;
using testing::Not;
using testing::StartsWith;

// A short grid and a fit (a few seconds at --speed 100).
constexpr const char* kShortGrid =
    "name: short_grid\nsteps:\n  - home\n"
    "  - null_offset_grid: {axes: [pitch, yaw], extent_deg: 0.3, step_deg: 0.1, settle_s: 0.2, frames: 3}\n"
    "  - calibrate: {method: differences}\n";

class Cli : public testing::Test {
 protected:
  CommandResult run(const std::vector<std::string>& args, const std::string& tag = "cli") const {
    return test::run_stand(args, tmp_.path(), tag, 300);
  }
  fs::path grid() const {
    if (!fs::exists(tmp_ / "short_grid.yaml")) test::write_file(tmp_ / "short_grid.yaml", kShortGrid);
    return tmp_ / "short_grid.yaml";
  }
  test::TempDir tmp_{"cli"};
};

// ---------------------------------------------------------------- progress and errors

// A port already taken: a job that fails (exit 1), in the same style as bad input.
TEST_F(Cli, EveryErrorComesInOneStyle) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(::listen(fd, 1), 0);
  socklen_t len = sizeof a;
  ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len), 0);
  const CommandResult taken = run({"emulate", "--modbus-port", std::to_string(ntohs(a.sin_port))}, "taken");
  ::close(fd);
  EXPECT_EQ(taken.code, 1) << taken.err;
  EXPECT_THAT(taken.err, StartsWith("fpss-stand: error: ")) << taken.err;

  const CommandResult unknown_command = run({"frobnicate"});
  const CommandResult unknown_option = run({"run", grid().string(), "--frobnicate"});
  const CommandResult missing = run({"calibrate", "--out", (tmp_ / "c.json").string()});
  const CommandResult bad_file = run({"calibrate", "--data", (tmp_ / "none.csv").string(), "--out", (tmp_ / "c.json").string()});
  for (const CommandResult* r : {&unknown_command, &unknown_option, &missing, &bad_file}) {
    EXPECT_EQ(r->code, 2) << r->err;
    EXPECT_THAT(r->err, StartsWith("fpss-stand: error: ")) << r->err;
  }
}

}  // namespace
}  // namespace fpss
