// Emulator throughput: sensor frames per wall second off the pty at RATE 200 and --speed 50; Modbus reads per second.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <benchmark/benchmark.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "fixtures/emulator.h"
#include "tests/fixtures/wire_util.h"
#include "tests/support/test_support.h"
#include "tests/support/emulator_options.h"

namespace {

using Clock = std::chrono::steady_clock;

double process_cpu_s() {  // the emulator's threads and the reader: one process
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + (u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-6;
}

// A reader on the pty counts good frames for `seconds` of wall time. Target: rate * speed frames
// per wall second (200 Hz x 50 = 10,000), none lost to the emulator falling behind.
void BM_SensorStream(benchmark::State& state) {
  const int rate_hz = static_cast<int>(state.range(0));
  const double speed = static_cast<double>(state.range(1));
  const double seconds = 3.0;
    fpss::Emulator emu(fpss::test::running_emulator_options(speed));
  emu.start();
  fpss::wiretest::PtyHost host(emu.endpoints().sensor_pty);
  if (host.ask("RATE " + std::to_string(rate_hz)) != "OK" || host.ask("START") != "OK") {
    state.SkipWithError("sensor did not accept RATE/START");
    return;
  }
  host.read_until([&] { return host.scanner.samples.size() >= 100; }, 10.0);  // warm up
  for (auto _ : state) {
    const std::size_t n0 = host.scanner.samples.size();
    const auto s0 = emu.stats().sensor;
    const double b0 = emu.bench_time_s();
    const double cpu0 = process_cpu_s();
    const auto t0 = Clock::now();
    while (Clock::now() - t0 < std::chrono::duration<double>(seconds)) host.pump(5);
    const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
    const double bench = emu.bench_time_s() - b0;
    const auto s1 = emu.stats().sensor;
    const double frames = static_cast<double>(host.scanner.samples.size() - n0);
    state.counters["frames_per_wall_s"] = frames / wall;
    state.counters["target_per_wall_s"] = rate_hz * speed;
    state.counters["frames_per_bench_s"] = frames / bench;
    state.counters["bench_s_per_wall_s"] = bench / wall;
    state.counters["cpu_s_per_wall_s"] = (process_cpu_s() - cpu0) / wall;
    state.counters["dropped"] = static_cast<double>(s1.frames_dropped - s0.frames_dropped);
    state.counters["bad_crc"] = static_cast<double>(host.scanner.bad_crc());
    state.SetIterationTime(wall);
  }
  // seq must run without gaps: every generated frame arrived.
  const auto& s = host.scanner.samples;
  std::size_t gaps = 0;
  for (std::size_t i = 1; i < s.size(); ++i) gaps += static_cast<uint16_t>(s[i].seq - s[i - 1].seq) != 1;
  state.counters["seq_gaps"] = static_cast<double>(gaps);
}
BENCHMARK(BM_SensorStream)->Args({200, 50})->Args({50, 20})->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);

// A bare libmodbus read of the 15 input registers against the emulated gimbal on loopback.
void BM_ModbusReadState(benchmark::State& state) {
    fpss::Emulator emu(fpss::test::running_emulator_options(20));
  emu.start();
  fpss::wiretest::ModbusClient c(emu.endpoints().modbus_port);
  for (auto _ : state) benchmark::DoNotOptimize(c.input(0, 15));
  state.counters["reads_per_s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ModbusReadState)->Unit(benchmark::kMicrosecond);

// ---------------------------------------------------------------- soak

// RSS (kB) and threads of a process, from /proc/PID/status.
std::pair<long, long> rss_kb_and_threads(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  long rss = -1, threads = -1;
  for (std::string l; std::getline(in, l);) {
    if (l.rfind("VmRSS:", 0) == 0) rss = std::stol(l.substr(6));
    if (l.rfind("Threads:", 0) == 0) threads = std::stol(l.substr(8));
  }
  return {rss, threads};
}

// The emulator (`fpss-stand emulate`, a child process, so its memory and threads are its own) serves
// random valid Modbus traffic from 8 clients while 2,000 connect/disconnects flood it, for
// FPSS_SOAK_S seconds (default 20; run it once with 600). It must stay up, its threads bounded
// (<= 2 x --max-clients + a few) and its memory flat. Prints RSS and threads before, at most and after.
void BM_EmulatorSoak(benchmark::State& state) {
  const char* env = std::getenv("FPSS_SOAK_S");
  const double soak_s = env ? std::atof(env) : 20.0;
  fpss::test::TempDir dir("soak");
  fpss::test::Child emu = fpss::test::start_emulate({"--modbus-port", "0", "--max-clients", "32", "--speed", "20"},
                                                    dir / "emulate.err");
  const auto line = emu.line();
  const auto colon = line ? line->rfind(':') : std::string::npos;
  if (colon == std::string::npos) {
    state.SkipWithError("the emulator did not start");
    return;
  }
  const int port = std::stoi(line->substr(colon + 1));
  while (auto l = emu.line()) if (*l == "ready") break;

  std::atomic<bool> stop{false};
  std::atomic<uint64_t> requests{0}, errors{0}, reconnects{0}, floods{0}, flood_refused{0};
  auto client = [&](int id) {
    std::mt19937_64 rng(1000 + id);
    std::optional<fpss::wiretest::ModbusClient> c;
    while (!stop) {
      try {
        if (!c) c.emplace(port, 2.0);
        switch (rng() % 6) {
          case 0:
          case 1: {
            const int a = static_cast<int>(rng() % 15), n = 1 + static_cast<int>(rng() % (15 - a));
            c->input(a, n);
            break;
          }
          case 2: c->holding(0, 13); break;
          case 3: {  // a move within +-1000 arcsec, targets and command in one write
            auto t = fpss::wiretest::words(static_cast<int32_t>(rng() % 2'000'000) - 1'000'000);
            c->write(0, fpss::wiretest::cat(t, fpss::wiretest::words(0)));
            c->write(11, uint16_t{1});
            break;
          }
          case 4: c->write(11, uint16_t{2}); break;  // stop
          case 5: c->write(12, uint16_t{0}); break;  // watchdog off
        }
        ++requests;
        // Paced (about 500 requests/s per client, as a polling driver), so the soak measures
        // staying power, not the loopback's top speed, on a shared machine.
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
      } catch (const std::exception&) {
        ++errors;  // an exception answer (03 for a move while moving is fine) or a dropped link
        if (c && rng() % 4 == 0) {
          c.reset();
          ++reconnects;
        }
      }
    }
  };
  auto flood = [&] {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    const auto start = Clock::now();
    for (int i = 0; i < 2000 && !stop; ++i) {
      // Spread over the run: connection i at i/2000 of the soak.
      const auto due = start + std::chrono::duration<double>(soak_s * 0.9 * i / 2000);
      while (!stop && Clock::now() < due) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
      if (fd < 0) continue;
      if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) ++flood_refused;
      ::close(fd);
      ++floods;
    }
  };

  for (auto _ : state) {
    // Before: the emulator serving 8 connected clients.
    std::vector<std::thread> threads;
    for (int id = 0; id < 8; ++id) threads.emplace_back(client, id);
    while (requests < 800 && emu.pid() > 0) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    const auto [rss0, thr0] = rss_kb_and_threads(emu.pid());
    threads.emplace_back(flood);
    long rss_max = rss0, thr_max = thr0;
    const auto t0 = Clock::now();
    while (Clock::now() - t0 < std::chrono::duration<double>(soak_s)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      const auto [rss, thr] = rss_kb_and_threads(emu.pid());
      if (rss < 0) break;  // the emulator is gone
      rss_max = std::max(rss_max, rss);
      thr_max = std::max(thr_max, thr);
    }
    stop = true;
    for (auto& t : threads) t.join();
    const auto [rss1, thr1] = rss_kb_and_threads(emu.pid());
    const double wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
    state.SetIterationTime(wall_s);
    state.counters["rss_before_kB"] = static_cast<double>(rss0);
    state.counters["rss_max_kB"] = static_cast<double>(rss_max);
    state.counters["rss_after_kB"] = static_cast<double>(rss1);
    state.counters["threads_before"] = static_cast<double>(thr0);
    state.counters["threads_max"] = static_cast<double>(thr_max);
    state.counters["threads_after"] = static_cast<double>(thr1);
    state.counters["requests"] = static_cast<double>(requests);
    state.counters["client_errors"] = static_cast<double>(errors);
    state.counters["flood_connects"] = static_cast<double>(floods);
    std::printf("soak %.0f s: emulator RSS %ld kB before, %ld kB at most, %ld kB after; threads %ld before, %ld at most, "
                "%ld after; %llu requests from 8 clients (%llu errors, %llu reconnects), %llu flood connects "
                "(%llu refused by the kernel)\n",
                wall_s, rss0, rss_max, rss1, thr0, thr_max, thr1, (unsigned long long)requests.load(),
                (unsigned long long)errors.load(), (unsigned long long)reconnects.load(),
                (unsigned long long)floods.load(), (unsigned long long)flood_refused.load());
    if (rss1 < 0) state.SkipWithError("the emulator died during the soak");
  }
  emu.signal(SIGTERM);
  const int code = emu.wait(30);
  const std::string err = emu.err();
  const auto at = err.find("emulate: stopped");
  std::printf("emulator exit %d; %s", code, at == std::string::npos ? err.c_str() : err.substr(at).c_str());
  if (code != 0) state.SkipWithError("the emulator did not exit 0");
}
BENCHMARK(BM_EmulatorSoak)->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);

}  // namespace
