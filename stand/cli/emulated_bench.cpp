#include "stand/cli/emulated_bench.h"
#include "stand/cli/file_hints.h"

#include <fmt/format.h>

#include <charconv>
#include <filesystem>
#include <limits>

#include "base/errors.h"
#include "calib/coefficients.h"
#include "fixtures/bench.h"
#include "fixtures/emulator.h"
#include "fixtures/faults.h"

namespace fpss::cli {

namespace fs = std::filesystem;

namespace {

// CLI11 prefixes the option's name ("--fault: ..."); the spec parsers' messages start with it too.
std::string without_option_name(const std::string& message, const std::string& option) {
  const std::string lead = option + " ";
  return message.rfind(lead, 0) == 0 ? message.substr(lead.size()) : message;
}

void add_emulated_bench_options(CLI::App* sub, EmulatedBenchArgs& a) {
  a.options.push_back(
      sub->add_option("--speed", a.speed, "Emulator: bench clock speed-up (default 20)")->check(speed_check()));
  a.options.push_back(
      sub->add_option("--seed", a.seed, "Emulator: seed of all bench noise (default 1)")->check(seed_check()));
  a.options.push_back(sub->add_option("--bench", a.bench, "Emulator: bench file (YAML)"));
  expect_file(sub, a.options.back(), a.bench, FileKind::bench);
  // One value per occurrence (--effect A --effect B), so a positional argument after them stays one.
  a.options.push_back(sub->add_option("--effect", a.effects, "Emulator: injected effect NAME:key=value,... (repeatable)")
                          ->allow_extra_args(false)
                          ->check(effect_check()));
  a.options.push_back(
      sub->add_option("--fault", a.faults, "Emulator: fault NAME[:key=value,...] (repeatable; docs/emulator.md)")
          ->allow_extra_args(false)
          ->check(fault_check()));
  a.options.push_back(sub->add_option("--truth", a.truth, "Emulator: coefficient file of the sensor's truth"));
  expect_file(sub, a.options.back(), a.truth, FileKind::coefficients);
}

}  // namespace

CLI::Validator speed_check() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        double v = 0;
        if (!CLI::detail::lexical_cast(text, v)) return "expected a number, got " + text;
        return emulator_speed_error(v);
      },
      fmt::format("{}..{}", kMinEmulatorSpeed, kMaxEmulatorSpeed));
}

CLI::Validator seed_check() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        // Decimal digits only, within uint64_t: no sign, no wrap, no saturation at the maximum.
        uint64_t v = 0;
        const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
        if (!text.empty() && ec == std::errc() && end == text.data() + text.size()) return {};
        return fmt::format("expected a whole number in 0..{}, got {}", std::numeric_limits<uint64_t>::max(), text);
      },
      "0..2^64-1");
}

// A validator that `parse` accepts the value: its own message when it does not, without its option's name.
template <typename Parse>
CLI::Validator parses(Parse parse, const char* option) {
  return CLI::Validator(
      [parse, option](std::string& spec) -> std::string {
        try {
          (void)parse(spec);
          return {};
        } catch (const InputError& e) {
          return without_option_name(e.what(), option);
        }
      },
      "");
}

CLI::Validator effect_check() {
  return parses([](const std::string& spec) { return parse_effect(spec); }, "--effect");
}

CLI::Validator fault_check() {
  return parses([](const std::string& spec) { return parse_fault(spec); }, "--fault");
}

void add_bench_choice_options(CLI::App* sub, BenchChoiceArgs& a, const std::string& stand_help,
                              const std::string& emulate_help) {
  expect_file(sub, sub->add_option("--stand", a.stand_file, stand_help), a.stand_file, FileKind::stand);
  sub->add_flag("--emulate", a.emulate, emulate_help);
  add_emulated_bench_options(sub, a.emu);
}

void require_emulate_for_options(const EmulatedBenchArgs& a, const std::string& command) {
  for (auto* o : a.options) {
    if (o->count() > 0) throw InputError(fmt::format("{}: {} needs --emulate", command, o->get_name()));
  }
}

EmulatorSpec emulator_spec(const EmulatedBenchArgs& a, const std::string& unit_serial) {
  EmulatorSpec e;
  e.speed = a.speed;
  e.seed = a.seed;
  e.bench_file = a.bench.empty() ? "" : fs::absolute(a.bench).string();
  e.truth_file = a.truth.empty() ? "" : fs::absolute(a.truth).string();
  e.unit_serial = unit_serial;
  for (const auto& spec : a.effects) {
    const Effect eff = parse_effect(spec);
    e.effects.push_back(eff.name == "coefficients" ? spec : format_effect(eff));
  }
  // Relative files named inside effects are the caller's: make them absolute for the child.
  for (auto& spec : e.effects) {
    const auto at = spec.find("file=");
    if (at != std::string::npos) {
      const auto end = spec.find(',', at);
      const std::string file = spec.substr(at + 5, end == std::string::npos ? std::string::npos : end - at - 5);
      spec.replace(at + 5, file.size(), fs::absolute(file).string());
    }
  }
  if (!e.bench_file.empty()) (void)load_bench_file(e.bench_file);
  if (!e.truth_file.empty()) (void)load_coefficients(e.truth_file);
  e.faults = a.faults;
  e.exe = this_binary();
  return e;
}

fs::path this_binary() {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path("/proc/self/exe") : self;
}

}  // namespace fpss::cli
