// The emulated-bench options `run` and `accept` share, and the emulator child they describe.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "stand/cli/emulator_contract.h"

namespace fpss::cli {

struct EmulatedBenchArgs {
  double speed = 20;
  uint64_t seed = 1;
  std::string bench, truth;
  std::vector<std::string> effects, faults;
  std::vector<CLI::Option*> options;  // every option above, for "needs --emulate"
};

// --speed, --seed, --bench, --effect (repeatable), --fault (repeatable), --truth.
void add_emulated_bench_options(CLI::App* sub, EmulatedBenchArgs& a);
// InputError "<command>: --x needs --emulate" for the first of these options given.
void require_emulate_for_options(const EmulatedBenchArgs& a, const std::string& command);
// The child's spec, checked now (effects parsed, bench and truth files read: InputError rather than
// a bench that will not start), files made absolute, the binary resolved so run.json names it.
EmulatorSpec emulator_spec(const EmulatedBenchArgs& a, const std::string& unit_serial);
// The fpss-stand binary running now (it serves the emulated bench as a child).
std::filesystem::path this_binary();

}  // namespace fpss::cli
