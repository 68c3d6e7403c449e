// fpss-stand emulate: the emulated bench (gimbal over Modbus, sensor on a pty) until SIGINT/SIGTERM.
#include <pthread.h>
#include <signal.h>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cstdio>
#include <sstream>
#include <memory>
#include <string>
#include <vector>

#include "base/errors.h"
#include "base/text_file.h"
#include "calib/coefficients.h"
#include "fixtures/emulator.h"
#include "stand/cli/commands.h"
#include "stand/cli/emulated_bench.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"
#include "stand/contract/emulator_contract.h"

namespace fpss::cli {

namespace {

struct EmulateArgs {
  std::string bench_file, serial_link, truth_file, unit_serial, fault_file;
  std::string modbus_host = "127.0.0.1";
  int modbus_port = 1502;
  bool modbus_rtu = false, allow_remote = false;
  int max_clients = 32;
  double idle_timeout_s = 60.0;
  double speed = 20.0;
  uint64_t seed = 1;
  std::vector<std::string> effects, faults;
};

// Reads the fault file (one NAME:key=value,... per line, # comments) and arms each fault. A bad
// line is reported and skipped: the emulator keeps running for the other clients.
void inject_from_file(Emulator& emu, const std::string& path) {
  // A regular file of at most kMaxConfigFileBytes: a FIFO or /dev/zero there cannot stall or
  // swell the emulator.
  std::string text;
  try {
    text = read_text_file(path, "fault file", kMaxConfigFileBytes);
  } catch (const InputError& e) {
    fmt::print(stderr, "emulate: SIGUSR1: {}\n", e.what());
    return;
  }
  std::istringstream in(text);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    const auto b = line.find_first_not_of(" \t\r");
    if (b == std::string::npos || line[b] == '#') continue;
    const auto e = line.find_last_not_of(" \t\r");
    const std::string spec = line.substr(b, e - b + 1);
    try {
      emu.inject(spec);
      fmt::print(stderr, "emulate: fault {} armed (bench t={:.3f} s)\n", spec, emu.bench_time_s());
    } catch (const InputError& err) {
      fmt::print(stderr, "emulate: {}:{}: {}\n", path, n, err.what());
    }
  }
}

int run_emulate(const EmulateArgs& a, bool seed_given) {
  EmulatorOptions o;
  o.bench = a.bench_file.empty() ? default_bench_config() : load_bench_file(a.bench_file);
  // With a bench of several units, --truth and --unit-serial are the first unit's.
  if (!a.truth_file.empty()) (o.bench.sensors.empty() ? o.bench.truth : o.bench.sensors.front().truth) = load_coefficients(a.truth_file);
  if (!a.unit_serial.empty()) (o.bench.sensors.empty() ? o.bench.serial : o.bench.sensors.front().serial) = a.unit_serial;
  if (seed_given || a.bench_file.empty()) o.bench.seed = a.seed;
  for (const auto& e : a.effects) o.bench.effects.push_back(parse_effect(e));
  for (const auto& f : a.faults) o.faults.push_back(parse_fault(f));
  o.modbus_host = a.modbus_host;
  o.modbus_port = a.modbus_port;
  o.modbus_rtu = a.modbus_rtu;
  o.allow_remote = a.allow_remote;
  o.modbus_limits.max_clients = a.max_clients;
  o.modbus_limits.idle_timeout_s = a.idle_timeout_s;
  o.serial_link = a.serial_link;
  o.speed = a.speed;
  auto emu = std::make_unique<Emulator>(std::move(o));  // checks the options: InputError -> 2
  if (a.allow_remote && a.modbus_host.rfind("127.", 0) != 0) {
    fmt::print(stderr,
               "emulate: WARNING: serving Modbus on {} (--allow-remote): anyone who can reach this address can "
               "move the emulated gimbal; at most {} clients, idle ones closed after {} s\n",
               a.modbus_host, a.max_clients, a.idle_timeout_s);
  }

  // Signals are taken by sigwait below, so every thread started from here on blocks them.
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGUSR1);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  signal(SIGPIPE, SIG_IGN);  // a client hanging up must not kill the bench

  emu->start();
  const auto& ep = emu->endpoints();
  // The lines other programs wait for (procedure engine, tests): exactly these, then flush.
  namespace r = emulator_ready;
  std::printf("%.*s%s\n", int(r::gimbal.size()), r::gimbal.data(), ep.gimbal().c_str());
  if (a.modbus_rtu) std::printf("%.*s%s\n", int(r::gimbal_rtu.size()), r::gimbal_rtu.data(), ep.gimbal_rtu().c_str());
  for (size_t u = 0; u < ep.sensor_ptys.size(); ++u) {  // one line per unit, in the bench's order
    std::printf("%.*s%s\n", int(r::sensor.size()), r::sensor.data(), ep.sensor(u).c_str());
  }
  std::printf("%.*s\n", int(r::ready.size()), r::ready.data());
  std::fflush(stdout);
  std::vector<std::string> serials;
  for (const auto& u : emu->options().bench.units()) serials.push_back(u.serial);
  fmt::print(stderr, "emulate: bench clock x{} wall, seed {}, unit{} {}{}\n", a.speed, emu->options().bench.seed,
             serials.size() > 1 ? "s" : "", fmt::join(serials, ", "),
             a.serial_link.empty() ? "" : ", sensor linked at " + a.serial_link);

  for (;;) {
    int sig = 0;
    if (sigwait(&set, &sig) != 0) continue;
    if (sig == SIGUSR1) {
      if (a.fault_file.empty()) fmt::print(stderr, "emulate: SIGUSR1 ignored (no --fault-file)\n");
      else inject_from_file(*emu, a.fault_file);
      continue;
    }
    break;  // SIGINT or SIGTERM
  }
  const EmulatorStats s = emu->stats();
  emu->stop();
  fmt::print(stderr,
             "emulate: stopped at bench t={:.3f} s; modbus {} requests ({} exceptions, {} connections, {} refused, "
             "{} evicted, {} idle closed, at most {} at once); sensor {} "
             "frames written, {} dropped unread, {} commands; {} faults fired\n",
             s.bench_time_s, s.modbus_tcp.requests + s.modbus_rtu.requests,
             s.modbus_tcp.exceptions + s.modbus_rtu.exceptions, s.modbus_tcp.connections, s.modbus_tcp.refused,
             s.modbus_tcp.evicted, s.modbus_tcp.idle_closed, s.modbus_tcp.peak_active, s.sensor.frames_written,
             s.sensor.frames_dropped, s.sensor.commands, s.faults_fired);
  return 0;
}

}  // namespace

void add_emulate(CLI::App& app, Runner& run) {
  auto args = std::make_shared<EmulateArgs>();
  auto* sub = app.add_subcommand(
      "emulate", "Emulated bench: the gimbal over Modbus TCP (and RTU) and the sensor on a pty, one simulated bench");
  expect_file(sub,
              sub->add_option("--bench", args->bench_file, "Bench file (YAML): dynamics, noise, truth, effects")
                  ->check(CLI::ExistingFile),
              args->bench_file, FileKind::bench);
  sub->add_option("--modbus-port", args->modbus_port, "Modbus TCP port (0 picks a free one)")
      ->capture_default_str()
      ->check(CLI::Range(0, 65535));
  sub->add_option("--modbus-host", args->modbus_host, "Address the Modbus TCP server binds (an IPv4 address)")
      ->capture_default_str();
  sub->add_flag("--allow-remote", args->allow_remote,
                "Allow a --modbus-host other than loopback (127.x): the bench is then open to the network");
  sub->add_option("--max-clients", args->max_clients, "Modbus TCP clients served at once (1..1000)")
      ->capture_default_str();
  sub->add_option("--idle-timeout-s", args->idle_timeout_s,
                  "Close a Modbus TCP connection with no request for this long (0.1..86400 s)")
      ->capture_default_str();
  sub->add_flag("--modbus-rtu", args->modbus_rtu, "Also serve Modbus RTU (unit 1) on a pty; prints gimbal-rtu:");
  sub->add_option("--serial-link", args->serial_link, "Symlink to the sensor pty at this path (removed at exit)");
  sub->add_option("--speed", args->speed, "Bench clock runs this many times faster than the wall clock")
      ->capture_default_str()
      ->check(speed_check());
  auto* seed = sub->add_option("--seed", args->seed, "Seed of all bench noise")->capture_default_str()->check(seed_check());
  sub->add_option("--effect", args->effects, "Injected effect NAME:key=value,... (repeatable)")->check(effect_check());
  expect_file(sub,
              sub->add_option("--truth", args->truth_file, "Coefficient file: the sensor's true transfer function")
                  ->check(CLI::ExistingFile),
              args->truth_file, FileKind::coefficients);
  sub->add_option("--unit,--unit-serial", args->unit_serial, "Serial number the sensor reports (ID?)");
  sub->add_option("--fault", args->faults,
                  "Fault NAME[:key=value,...] with optional trigger at_s= or at_request= (repeatable, docs/emulator.md)")
      ->check(fault_check());
  sub->add_option("--fault-file", args->fault_file, "On SIGUSR1, arm the faults listed in this file (one per line)");
  examples(sub, {"fpss-stand emulate --modbus-port 5020 --serial-link /tmp/fpss-sensor --speed 10",
                 "fpss-stand emulate --bench procedures/two_unit_bench.yaml --effect drift:pitch_arcsec_per_s=0.01"});
  sub->callback([args, seed, &run] {
    run = [args, seed] { return run_emulate(*args, seed->count() > 0); };
  });
}

}  // namespace fpss::cli
