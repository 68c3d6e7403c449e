// Coverage of the accuracy criteria's expanded uncertainty U (docs/acceptance.md) on recordings of
// the independent generator (tests/support/acceptance_mc.h), with the gimbal's errors drawn from a
// reference file's u and without. Target: U covers the true value in 95 +- 2 % of cases.
#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <string>

#include "tests/support/acceptance_mc.h"

namespace fpss {
namespace {

void BM_AccuracyCriteriaCoverage(benchmark::State& state, bool with_reference) {
  const int recordings = test::mc::env_int("FPSS_MC_RECORDINGS", 200);
  const std::string truth_name = "a-6-fpss1";
  const CoefficientSet truth = load_published(truth_name);
  test::mc::Design design;
  design.verification = true;
  const std::filesystem::path ref_path = test::source_dir() / "procedures" / "reference_example.json";
  std::optional<ReferenceCalibration> reference;
  if (with_reference) {
    design.gimbal_errors = ref_path;
    reference = load_reference_calibration(ref_path);
  }
  const AcceptanceLimits limits = load_acceptance_limits(default_limits_path());
  for (auto _ : state) {
    test::TempDir dir("acceptance-coverage");
    const auto files = test::mc::generate(published_dir() / (truth_name + ".json"), dir / "rec", recordings,
                                          with_reference ? 5151 : 1515, design);
    const auto tallies = test::mc::accuracy_coverage(files, design, truth, reference, limits);
    fmt::print("\nAccuracy criteria's U coverage ({}, {} recordings of the independent generator, grid + "
               "verification):\n",
               with_reference ? "gimbal errors drawn from reference_example.json's u" : "no reference errors",
               files.size());
    for (const auto& [name, t] : tallies) {
      fmt::print("  {:<18} {:5.1f} % of {} (mean |measured - true| / U {:.2f}; target 95 +- 2 %)\n", name,
                 100 * t.rate(), t.cases, t.sum_ratio / static_cast<double>(std::max<size_t>(1, t.cases)));
      state.counters["coverage_" + name] = t.rate();
    }
  }
}
BENCHMARK_CAPTURE(BM_AccuracyCriteriaCoverage, reference_errors, true)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK_CAPTURE(BM_AccuracyCriteriaCoverage, no_reference, false)->Iterations(1)->Unit(benchmark::kSecond);

}  // namespace
}  // namespace fpss
