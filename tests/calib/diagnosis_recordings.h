// The simulated-bench recordings the diagnosis's tests share: a bench with a non-monotonic
// temperature, a small grid and slews at two rates, and the diagnosis options that go with them.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "calib/diagnosis/diagnosis.h"
#include "fixtures/bench.h"
#include "fixtures/recording.h"

namespace fpss::diagnosis_test {

inline constexpr double kSettle = 0.2;

inline BenchConfig bench(uint64_t seed, const std::vector<std::string>& effects, bool noisy = true) {
  BenchConfig c = default_bench_config();
  c.seed = seed;
  if (!noisy) {
    c.count_noise = 0;
    c.encoder_noise_arcsec = 0;
  }
  // Ramp plus sinusoid: temperature is not a function of time alone.
  c.temperature.ramp_c_per_s = 0.02;
  c.temperature.amplitude_c = 1.5;
  c.temperature.period_s = 40;
  for (const auto& e : effects) c.effects.push_back(parse_effect(e));
  return c;
}

inline SessionPlan plan(bool grid = true, bool slews = true) {
  SessionPlan p;
  if (grid) {
    GridPlan g;
    g.extent_deg = 0.36;
    g.step_deg = 0.12;
    g.samples_per_dwell = 20;
    g.sample_rate_hz = 50;
    g.settle_s = kSettle;
    p.grids.push_back(g);
  }
  if (slews) {
    for (int axis : {0, 1}) {
      for (double rate : {300.0, 600.0}) p.slews.push_back(SlewPlan{axis, 1200.0, rate, 0.02});
    }
  }
  return p;
}

inline DiagnosisOptions options() {
  DiagnosisOptions o;
  o.settle_s = kSettle + 0.005;  // the recorder sees the arrival within its 10 ms poll
  return o;
}

}  // namespace fpss::diagnosis_test
