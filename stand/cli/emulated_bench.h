// The bench options `run`, `accept` and `serve` share (a stand file or the emulated bench), and the
// emulator child they describe.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "stand/contract/emulator_contract.h"

namespace fpss::cli {

struct EmulatedBenchArgs {
  double speed = 20;
  uint64_t seed = 1;
  std::string bench, truth;
  std::vector<std::string> effects, faults;
  std::vector<CLI::Option*> options;  // every option above, for "needs --emulate"
};

// Checks of the emulated bench's options, run while the command line is parsed, so a value out of
// range is exit 2 before any folder is made or any child starts. Each asks the emulator's own
// definition (its speed range, parse_effect, parse_fault): the ranges are written once, in fixtures/.
CLI::Validator speed_check();   // --speed: kMinEmulatorSpeed..kMaxEmulatorSpeed
CLI::Validator seed_check();    // --seed: a whole number 0..2^64-1 (strtoull would take -1 as 2^64-1)
CLI::Validator effect_check();  // --effect NAME:key=value,...: a known effect, its keys and values
CLI::Validator fault_check();   // --fault NAME[:key=value,...]: a known fault, its keys, values, trigger

// The bench a command runs on: a real one (its stand file) or the emulated one.
struct BenchChoiceArgs {
  std::string stand_file;
  bool emulate = false;
  EmulatedBenchArgs emu;
};

// --stand FILE and --emulate, with what each means to the command, then the emulated bench's options:
// --speed, --seed, --bench, --effect (repeatable), --fault (repeatable), --truth.
void add_bench_choice_options(CLI::App* sub, BenchChoiceArgs& a, const std::string& stand_help,
                              const std::string& emulate_help);
// InputError "<command>: --x needs --emulate" for the first of these options given.
void require_emulate_for_options(const EmulatedBenchArgs& a, const std::string& command);
// The child's spec, checked now (effects parsed, bench and truth files read: InputError rather than
// a bench that will not start), files made absolute, the binary resolved so run.json names it.
EmulatorSpec emulator_spec(const EmulatedBenchArgs& a, const std::string& unit_serial);
// The fpss-stand binary running now (it serves the emulated bench as a child).
std::filesystem::path this_binary();

}  // namespace fpss::cli
