// calibrate() on null-to-offset recordings of 2e3..2e6 samples: time, and the memory the fit
// takes beyond its input (peak RSS reset per run through /proc/self/clear_refs).
#include <benchmark/benchmark.h>

#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <string>

#include "calib/calibrator.h"
#include "calib/coefficients.h"
#include "calib/monte_carlo.h"
#include "calib/streaming.h"

namespace fpss {
namespace {

constexpr int kSamplesPerDwell = 5;

// A recording with the bench's noise model (0.3-count Gaussian then integer counts, 0.05 arcsec
// reference noise), built directly: the bench simulation integrates gimbal dynamics per
// millisecond, far too slow for two million samples. Offsets alternate pitch / yaw at seeded
// uniform positions within +-0.42 deg, each between two null dwells.
SampleTable make_recording(size_t samples, uint64_t seed) {
  const CoefficientSet truth = load_published("a-6-fpss1");
  const AxisModel a = truth.alpha_model(), b = truth.beta_model();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(-0.42 * 3600, 0.42 * 3600);
  const double a0 = a.counts_for_angle(0.0), b0 = b.counts_for_angle(0.0);
  SampleTable t;
  t.origin = "bench";
  t.reserve(samples);
  int64_t step = 0;
  double time = 0;
  for (size_t dwell = 0; t.size() < samples; ++dwell) {
    const bool offset = dwell % 2 == 1;
    const bool along_pitch = dwell % 4 == 1;
    const double ref = offset ? u(rng) : 0.0;
    const double p = offset && along_pitch ? ref : 0.0, y = offset && !along_pitch ? ref : 0.0;
    const double na = p == 0.0 ? a0 : a.counts_for_angle_unchecked(arcsec_to_rad(p));
    const double nb = y == 0.0 ? b0 : b.counts_for_angle_unchecked(arcsec_to_rad(y));
    ++step;
    for (int i = 0; i < kSamplesPerDwell && t.size() < samples; ++i) {
      time += 0.1;
      t.push_back(Sample{time, offset ? Phase::offset : Phase::null, step, p + 0.05 * g(rng), y + 0.05 * g(rng),
                         std::round(na + 0.3 * g(rng)), std::round(nb + 0.3 * g(rng))});
    }
    time += 2.0;
  }
  return t;
}

long status_kb(const char* key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const size_t n = std::strlen(key);
  while (std::getline(in, line)) {
    if (line.compare(0, n, key) == 0) return std::stol(line.substr(n + 1));
  }
  return -1;
}

bool reset_peak() {
  std::ofstream f("/proc/self/clear_refs");
  f << "5";
  return static_cast<bool>(f);
}

void BM_Calibrate(benchmark::State& state) {
  const size_t n = static_cast<size_t>(state.range(0));
  const SampleTable t = make_recording(n, 42);
  CalibrationOptions opts;
  opts.threads = 2;
  double extra_mb = 0, max_pitch_res = 0;
  bool peak_ok = true;
  for (auto _ : state) {
    state.PauseTiming();
    peak_ok = reset_peak() && peak_ok;
    const long base_kb = status_kb("VmRSS:");
    state.ResumeTiming();
    const CalibrationReport r = calibrate(t, opts);
    state.PauseTiming();
    extra_mb = std::max(extra_mb, (status_kb("VmHWM:") - base_kb) / 1024.0);
    max_pitch_res = r.pitch.residuals.rms_arcsec;
    benchmark::DoNotOptimize(r.pitch.coeffs);
    state.ResumeTiming();
  }
  const double table_mb =
      static_cast<double>(n) * (6 * sizeof(double) + sizeof(int64_t) + sizeof(Phase)) / (1024.0 * 1024.0);
  state.counters["samples"] = static_cast<double>(n);
  state.counters["fit_peak_MB"] = peak_ok ? extra_mb : -1;  // beyond the input table
  state.counters["fit_bytes_per_sample"] = peak_ok ? extra_mb * 1024 * 1024 / static_cast<double>(n) : -1;
  state.counters["table_MB"] = table_mb;
  state.counters["rms_pitch_arcsec"] = max_pitch_res;
}

BENCHMARK(BM_Calibrate)->Arg(2000)->Arg(20000)->Arg(200000)->Arg(2000000)->Unit(benchmark::kMillisecond);

// The command's path: calibrate_csv on the recording written as a samples file. Peak memory of the
// whole process during the call (VmHWM after a reset, the table freed before): what `fpss-stand
// calibrate` needs beyond its code. Target: <= 50 MB at 2 million rows.
void BM_CalibrateFile(benchmark::State& state) {
  const size_t n = static_cast<size_t>(state.range(0));
  const std::string path = "/tmp/fpss-bench-calib-" + std::to_string(::getpid()) + "-" + std::to_string(n) + ".csv";
  {
    const SampleTable t = make_recording(n, 42);
    write_samples_csv(path, t);
  }
  CalibrationOptions opts;
  opts.threads = 2;
  double peak_mb = 0, rss_before_mb = 0;
  bool peak_ok = true;
  size_t outliers = 0;
  for (auto _ : state) {
    state.PauseTiming();
    peak_ok = reset_peak() && peak_ok;
    rss_before_mb = status_kb("VmRSS:") / 1024.0;
    state.ResumeTiming();
    const CalibrationReport r = calibrate_csv(path, opts);
    state.PauseTiming();
    peak_mb = std::max(peak_mb, status_kb("VmHWM:") / 1024.0);
    outliers = r.outliers.any.outlier_frames;
    benchmark::DoNotOptimize(r.pitch.coeffs);
    state.ResumeTiming();
  }
  std::remove(path.c_str());
  state.counters["rows"] = static_cast<double>(n);
  state.counters["peak_MB"] = peak_ok ? peak_mb : -1;  // whole process, during the call
  state.counters["rss_before_MB"] = rss_before_mb;
  state.counters["fit_bytes_per_row"] = peak_ok ? (peak_mb - rss_before_mb) * 1024 * 1024 / static_cast<double>(n) : -1;
  state.counters["outlier_frames"] = static_cast<double>(outliers);
}

BENCHMARK(BM_CalibrateFile)->Arg(2000)->Arg(200000)->Arg(2000000)->Unit(benchmark::kMillisecond)->Iterations(1);

// The JCGM 101 check of the budget (calibrate --monte-carlo N) on a 20,000-sample calibration with
// the example reference calibration: N trials per axis, the reference's error model per trial.
void BM_MonteCarloCheck(benchmark::State& state) {
  CalibrationOptions o;
  o.threads = 1;
  o.reference = load_reference_calibration(std::string(FPSS_SOURCE_DIR) + "/procedures/reference_example.json");
  const CalibrationReport rep = calibrate(make_recording(20000, 3), o);
  for (auto _ : state) {
    const MonteCarloCheck mc = monte_carlo_check(rep, o, static_cast<size_t>(state.range(0)), 1);
    benchmark::DoNotOptimize(mc.axes.data());
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_MonteCarloCheck)->Arg(100000)->Arg(1000000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace fpss
