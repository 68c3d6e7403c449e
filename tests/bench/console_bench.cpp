// The console's cost to a run: procedures/discrete_grid.yaml on the emulated bench (default
// speed-up), alone (`fpss-stand run`) and queued through `fpss-stand serve` with a live event stream
// reading it, alternately. Time = the run's session wall time from its run.json (engine start to
// stop), so queueing is not counted. Target: under the console at most 5 % more.
#include <benchmark/benchmark.h>
#include <httplib.h>

#include <atomic>
#include <regex>
#include <thread>

#include <nlohmann/json.hpp>

#include "tests/support/test_support.h"

namespace {

using namespace fpss::test;
using json = nlohmann::json;

fs::path procedure() { return source_dir() / "procedures" / "discrete_grid.yaml"; }

double engine_wall_s(const fs::path& run_dir) {
  const json doc = json::parse(read_file(run_dir / "run.json"));
  return doc["sessions"].back()["engine"]["wall_s"].get<double>();
}

fs::path only_run(const fs::path& runs) {
  for (const auto& e : fs::directory_iterator(runs)) {
    if (e.is_directory() && e.path().filename().string()[0] != '.') return e.path();
  }
  return {};
}

void BM_RunAlone(benchmark::State& state) {
  for (auto _ : state) {
    TempDir t;
    const auto r = run_command(stand_argv({"run", procedure().string(), "--emulate", "--runs-dir", (t / "runs").string(),
                                           "--quiet", "--no-progress"}), t.path(), "run", 300);
    if (r.code != 0) state.SkipWithError(("run failed: " + r.err).c_str());
    state.SetIterationTime(engine_wall_s(only_run(t / "runs")));
  }
}

void BM_RunUnderConsole(benchmark::State& state) {
  TempDir t;
  Child serve(stand_argv({"serve", "--emulate", "--runs-dir", (t / "runs").string(), "--listen", "127.0.0.1:0"}), fs::path(),
              t / "serve.err");
  std::smatch m;
  const std::string banner = serve.line(30).value_or("");
  if (!std::regex_search(banner, m, std::regex(R"(:(\d+)/)"))) {
    state.SkipWithError("serve did not start");
    return;
  }
  const int port = std::stoi(m[1]);
  std::string tok = read_file(t / "runs" / "console.token");
  tok.pop_back();
  httplib::Client c("127.0.0.1", port);
  const httplib::Headers auth{{"Authorization", "Bearer " + tok}};
  int job = 0;
  for (auto _ : state) {
    ++job;
    c.Post("/api/jobs", auth, R"({"procedure":"discrete_grid.yaml"})", "application/json");
    std::string run_id;
    if (!wait_until([&] {
          const json j = json::parse(c.Get(("/api/jobs/" + std::to_string(job)).c_str())->body);
          if (j["run_id"].is_string()) run_id = j["run_id"];
          return !run_id.empty();
        }, 60, std::chrono::milliseconds(20))) {
      state.SkipWithError("the job never named its run");
      break;
    }
    // A page following the run: the event stream read to its end.
    std::atomic<size_t> bytes{0};
    std::thread reader([&] {
      httplib::Client s("127.0.0.1", port);
      s.set_read_timeout(30, 0);
      s.Get(("/api/runs/" + run_id + "/stream").c_str(), [&](const char*, size_t n) {
        bytes += n;
        return true;
      });
    });
    const bool finished = wait_until([&] {
      const json j = json::parse(c.Get(("/api/jobs/" + std::to_string(job)).c_str())->body);
      return j["state"] == "finished";
    }, 300, std::chrono::milliseconds(50));
    reader.join();
    if (!finished) {
      state.SkipWithError("the run did not finish");
      break;
    }
    state.SetIterationTime(engine_wall_s(fpss::test::run_folder_of(t / "runs", run_id)));
    state.counters["stream_bytes"] = static_cast<double>(bytes.load());
  }
  serve.signal(SIGTERM);
  serve.wait(20);
}

}  // namespace

BENCHMARK(BM_RunAlone)->UseManualTime()->Unit(benchmark::kSecond)->Iterations(3);
BENCHMARK(BM_RunUnderConsole)->UseManualTime()->Unit(benchmark::kSecond)->Iterations(3);
