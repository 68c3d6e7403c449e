// fpss-stand serve: the web console of one stand (docs/console.md).
#include <signal.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <optional>
#include <thread>

#include <fmt/format.h>

#include "base/errors.h"
#include "stand/acceptance/acceptance.h"
#include "stand/cli/catalogue_option.h"
#include "stand/cli/commands.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"
#include "stand/cli/emulated_bench.h"
#include "stand/config/stand_config.h"
#include "stand/console/server.h"
#include "stand/session/run_folder.h"

namespace fpss::cli {

namespace {

namespace fs = std::filesystem;

struct ServeArgs : BenchChoiceArgs {
  std::string runs_dir = "runs", listen = "127.0.0.1:8080", procedures, catalogue;
  size_t max_clients = 8;
};

// The emulator options as `run`/`accept` take them, checked now (bad input is exit 2 here, not in a child).
std::vector<std::string> emulator_args(const EmulatedBenchArgs& e) {
  (void)emulator_spec(e, "");
  std::vector<std::string> a{"--speed", fmt::format("{}", e.speed), "--seed", std::to_string(e.seed)};
  if (!e.bench.empty()) a.insert(a.end(), {"--bench", fs::absolute(e.bench).string()});
  if (!e.truth.empty()) a.insert(a.end(), {"--truth", fs::absolute(e.truth).string()});
  for (const auto& x : e.effects) a.insert(a.end(), {"--effect", x});
  for (const auto& x : e.faults) a.insert(a.end(), {"--fault", x});
  return a;
}

int serve_command(const ServeArgs& a) {
  console::ConsoleOptions o;
  const auto colon = a.listen.rfind(':');
  if (colon == std::string::npos || colon == 0) throw InputError("serve --listen: ADDR:PORT, e.g. 127.0.0.1:8080");
  o.host = a.listen.substr(0, colon);
  if (o.host.size() > 2 && o.host.front() == '[' && o.host.back() == ']') o.host = o.host.substr(1, o.host.size() - 2);
  try {
    size_t used = 0;
    o.port = std::stoi(a.listen.substr(colon + 1), &used);
    if (used != a.listen.size() - colon - 1 || o.port < 0 || o.port > 65535) throw std::out_of_range("port");
  } catch (const std::exception&) {
    throw InputError(fmt::format("serve --listen {}: the port must be 0-65535", a.listen));
  }
  if (a.stand_file.empty() == !a.emulate) throw InputError("serve: give --stand STAND.yaml or --emulate (one of them)");
  if (!a.emulate) require_emulate_for_options(a.emu, "serve");
  if (a.max_clients < 1 || a.max_clients > 64) throw InputError("serve --max-clients: 1-64");
  o.runs_dir = fs::absolute(a.runs_dir);
  // The runs' catalogue: the option, FPSS_CATALOGUE or the stand file's `catalogue:`; the runs the
  // console starts are given the same.
  o.catalogue = chosen_catalogue(a.catalogue, a.stand_file.empty() ? "" : load_stand_file(a.stand_file).catalogue);
  o.emulate = a.emulate;
  if (a.emulate) o.emulator_args = emulator_args(a.emu);
  if (!a.stand_file.empty()) {
    if (!fs::is_regular_file(a.stand_file)) throw InputError(fmt::format("serve --stand {}: no such file", a.stand_file));
    o.stand_file = fs::absolute(a.stand_file);
  }
  o.procedures_dir = a.procedures.empty() ? shipped_procedures_dir() : fs::path(a.procedures);
  o.procedures_dir = fs::absolute(o.procedures_dir);
  if (!fs::is_directory(o.procedures_dir)) {
    throw InputError(fmt::format("serve --procedures {}: not a folder", o.procedures_dir.string()));
  }
  o.exe = this_binary();
  o.max_live_clients = a.max_clients;

  // SIGINT/SIGTERM end serve (never its runs: they are in their own sessions): a thread waits for them.
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  // One console per runs folder: two would each keep their own queue and start runs on one stand.
  fs::create_directories(o.runs_dir / ".console");
  std::optional<RunFolderLock> one_console;
  try {
    one_console.emplace(o.runs_dir / ".console", "console.lock", "the runs folder's console");
  } catch (const RunFolderBusy& e) {
    throw InputError(fmt::format("serve: {}", e.what()));
  }
  console::ConsoleServer server(o);
  server.bind();
  const std::string url = fmt::format("http://{}:{}/", o.host.find(':') != std::string::npos ? "[" + o.host + "]" : o.host,
                                      server.port());
  std::printf("fpss-stand serve: console at %s (runs folder %s)\n", url.c_str(), o.runs_dir.c_str());
  if (server.token().created) {
    std::printf("console token (printed once; kept in %s, mode 0600): %s\nopen %s#token=%s to control runs\n",
                (o.runs_dir / "console.token").c_str(), server.token().value.c_str(), url.c_str(),
                server.token().value.c_str());
  } else {
    std::printf("control needs the token in %s\n", (o.runs_dir / "console.token").c_str());
  }
  std::fflush(stdout);
  std::thread waiter([&server, set] {
    int sig = 0;
    sigwait(&set, &sig);
    server.stop();
  });
  server.serve();
  // serve() also returns when listening fails: wake the waiter either way.
  ::kill(::getpid(), SIGTERM);
  waiter.join();
  return 0;
}

}  // namespace

void add_serve(CLI::App& app, Runner& run) {
  auto a = std::make_shared<ServeArgs>();
  auto* sub = app.add_subcommand("serve", "Web console of one stand: live runs, queue, runs, unit history (docs/console.md)");
  sub->add_option("--runs-dir", a->runs_dir, "Runs folder (default runs/)");
  sub->add_option("--listen", a->listen, "ADDR:PORT to listen on (default 127.0.0.1:8080; port 0: any free port)");
  add_bench_choice_options(sub, *a, "Stand file (YAML) of the real bench",
                           "Runs use the emulated bench (each starts its own emulator child)");
  sub->add_option("--procedures", a->procedures, "Folder of procedures the start page offers (default procedures/)");
  sub->add_option("--max-clients", a->max_clients, "Live event streams at once (default 8)");
  add_catalogue_option(sub, a->catalogue);
  examples(sub, {"fpss-stand serve --emulate --runs-dir runs",
                 "fpss-stand serve --stand procedures/example_stand.yaml --listen 127.0.0.1:8081"});
  sub->callback([&run, a] { run = [a] { return serve_command(*a); }; });
}

}  // namespace fpss::cli
