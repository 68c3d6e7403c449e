// The catalogue's speed on both backends: the latency of one write (one transaction: a run's start,
// a calibration, a run's end) with 1, 4 and 16 writer processes at once, and `fpss-stand history`
// of a unit with 1,000 calibrations. SQLite is a real file (WAL, synchronous FULL); PostgreSQL a
// real server started for the run (tests/support/pg_server.h; fsync off there, see docs/fleet.md).
#include <benchmark/benchmark.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

#include "calib/coefficients.h"
#include "stand/catalogue/catalogue.h"
#include "tests/support/pg_server.h"
#include "tests/support/test_support.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

fpss::test::PgServer& pg() {
  static fpss::test::PgServer server;
  return server;
}

fpss::test::TempDir& tmp() {
  static fpss::test::TempDir dir("bench-catalogue");
  return dir;
}

std::string fresh_catalogue(int backend, const std::string& name) {
  if (backend == 0) return "sqlite:" + (tmp().path() / (name + ".db")).string();
  return pg().create_database(name);
}

fpss::CalibrationRecord calibration(const std::string& unit, const std::string& run_id, int i) {
  auto j = fpss::to_json(fpss::load_published("a-6-fpss1"));
  j["residuals"] = {{"pitch", {{"mean_abs_arcsec", 0.2 + 1e-4 * i}, {"points", 40}}}};
  auto c = fpss::CalibrationRecord::from_calibration_json(j, "bench");
  c.unit = unit;
  c.source = "run";
  c.run_id = run_id;
  c.date_utc = fmt::format("2024-01-01T00:00:{:02}Z", i % 60);
  return c;
}

// One writer process: `runs` runs of three transactions each; each transaction's latency in us
// goes to the pipe as a binary double.
void writer(const std::string& url, int w, int runs, int out_fd, int go_fd) {
  char ch;
  if (::read(go_fd, &ch, 1) != 0) ::_exit(2);  // EOF: everyone starts together
  auto cat = fpss::open_catalogue(url);
  std::vector<double> lat;
  auto timed = [&](auto&& f) {
    const auto t0 = Clock::now();
    f();
    lat.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
  };
  for (int i = 0; i < runs; ++i) {
    fpss::RunStart rs;
    rs.run_id = fmt::format("w{}-{}", w, i);
    rs.unit = fmt::format("SN-{}", (w + i) % 8);
    rs.procedure = "bench";
    rs.procedure_hash = "x";
    rs.run_dir = "/tmp/none";
    timed([&] { cat->record_run_start(rs); });
    timed([&] { cat->record_calibration(calibration(rs.unit, rs.run_id, i)); });
    timed([&] { cat->record_run_end(rs.run_id, fpss::RunOutcome::completed); });
  }
  const ssize_t n = ::write(out_fd, lat.data(), lat.size() * sizeof(double));
  ::_exit(n == static_cast<ssize_t>(lat.size() * sizeof(double)) ? 0 : 1);
}

void BM_CatalogueWrite(benchmark::State& state) {
  const int backend = static_cast<int>(state.range(0));
  const int writers = static_cast<int>(state.range(1));
  const int runs = 40;  // 120 transactions per writer
  static int round = 0;
  std::vector<double> all;
  for (auto _ : state) {
    const std::string url = fresh_catalogue(backend, fmt::format("w{}_{}_{}", writers, backend, round++));
    fpss::open_catalogue(url);  // the schema first: creation is not what is measured
    int go[2];
    if (::pipe(go) != 0) return state.SkipWithError("pipe");
    std::vector<std::pair<pid_t, int>> kids;
    for (int w = 0; w < writers; ++w) {
      int out[2];
      if (::pipe(out) != 0) return state.SkipWithError("pipe");
      std::fflush(nullptr);
      const pid_t pid = ::fork();
      if (pid == 0) {
        ::close(go[1]);
        ::close(out[0]);
        writer(url, w, runs, out[1], go[0]);
      }
      ::close(out[1]);
      kids.emplace_back(pid, out[0]);
    }
    ::close(go[0]);
    const auto t0 = Clock::now();
    ::close(go[1]);
    for (auto& [pid, fd] : kids) {
      std::vector<double> lat(static_cast<size_t>(runs) * 3);
      size_t got = 0;
      auto* p = reinterpret_cast<char*>(lat.data());
      while (got < lat.size() * sizeof(double)) {
        const ssize_t n = ::read(fd, p + got, lat.size() * sizeof(double) - got);
        if (n <= 0) break;
        got += static_cast<size_t>(n);
      }
      ::close(fd);
      if (fpss::test::wait_exit_code(pid) != 0 || got != lat.size() * sizeof(double)) {
        return state.SkipWithError("a writer failed");
      }
      all.insert(all.end(), lat.begin(), lat.end());
    }
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - t0).count());
  }
  std::sort(all.begin(), all.end());
  auto pct = [&](double q) { return all[std::min(all.size() - 1, static_cast<size_t>(q * all.size()))] / 1000.0; };
  state.counters["p50_ms"] = pct(0.50);
  state.counters["p99_ms"] = pct(0.99);
  state.counters["writes"] = static_cast<double>(all.size());
  state.SetLabel(backend == 0 ? "sqlite" : "postgresql");
}
BENCHMARK(BM_CatalogueWrite)
    ->ArgNames({"pg", "writers"})
    ->ArgsProduct({{0, 1}, {1, 4, 16}})
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

// A unit with 1,000 calibrations (each of its own run), made once per backend.
std::string history_catalogue(int backend) {
  static std::string made[2];
  if (!made[backend].empty()) return made[backend];
  const std::string url = fresh_catalogue(backend, fmt::format("hist_{}", backend));
  {
    auto cat = fpss::open_catalogue(url);
    for (int i = 0; i < 1000; ++i) {
      fpss::RunStart rs;
      rs.run_id = fmt::format("h-{:04}", i);
      rs.unit = "SN-HIST";
      rs.procedure = "bench";
      rs.procedure_hash = "x";
      rs.run_dir = "/tmp/none";
      cat->record_run_start(rs);
      cat->record_calibration(calibration(rs.unit, rs.run_id, i));
    }
  }
  return made[backend] = url;
}

// The catalogue's part: reading the 1,000 calibrations (coefficients JSON and residuals) in-process.
void BM_UnitHistory1000(benchmark::State& state) {
  const int backend = static_cast<int>(state.range(0));
  const auto cat = fpss::open_catalogue(history_catalogue(backend), fpss::Catalogue::Mode::read_only);
  for (auto _ : state) {
    const auto h = cat->unit_history("SN-HIST");
    if (h.size() != 1000) return state.SkipWithError("not 1000 calibrations");
    benchmark::DoNotOptimize(h.data());
  }
  state.SetLabel(backend == 0 ? "sqlite" : "postgresql");
}
BENCHMARK(BM_UnitHistory1000)->ArgName("pg")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// `fpss-stand history SERIAL --json` on that unit, as a user runs it: the read above plus each
// calibration compared with the one before it (999 comparisons of transfer functions).
void BM_History1000(benchmark::State& state) {
  const int backend = static_cast<int>(state.range(0));
  const std::string url = history_catalogue(backend);
  for (auto _ : state) {
    const auto t0 = Clock::now();
    const auto r = fpss::test::run_stand({"history", "SN-HIST", "--catalogue", url, "--json"}, tmp().path(), "hist", 300);
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - t0).count());
    if (r.code != 0) return state.SkipWithError(("history failed: " + r.err).c_str());
  }
  state.SetLabel(backend == 0 ? "sqlite" : "postgresql");
}
BENCHMARK(BM_History1000)->ArgName("pg")->Arg(0)->Arg(1)->Iterations(3)->UseManualTime()->Unit(benchmark::kMillisecond);

}  // namespace
