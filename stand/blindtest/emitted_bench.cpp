// Closing the loop: an emulator bench file from a diagnosis, the model as truth and the causes as
// effects (stand/blindtest/blindtest.h, write_emitted_bench).
#include <fmt/format.h>

#include <filesystem>

#include "base/text_file.h"
#include "stand/blindtest/blindtest.h"

namespace fpss {

void write_emitted_bench(const std::string& bench_path, const Diagnosis& d, const std::string& model_path) {
  namespace fs = std::filesystem;
  const fs::path bench = fs::absolute(bench_path);
  fs::path truth = fs::absolute(model_path);
  std::string y = fmt::format("# Emulator bench file written by `fpss-stand diagnose --emit-bench` from {}\n"
                              "# verdict: {}; the model as truth, the diagnosed causes as effects.\n",
                              d.source, d.verdict);
  y += fmt::format("truth: \"{}\"\n", truth.lexically_relative(bench.parent_path()).string());
  y += "effects:\n";
  if (d.causes.empty()) y += "  []\n";
  for (const auto& c : d.causes) {
    if (c.name == "coefficients") {
      CoefficientSet set = load_coefficients(truth);
      set.alpha = c.params.at("alpha").get<AxisCoeffs>();
      set.beta = c.params.at("beta").get<AxisCoeffs>();
      set.extra["source"] = "diagnose --emit-bench: the refitted transfer function";
      const fs::path cf = emitted_coefficients_path(bench_path);
      save_coefficients(cf, set);
      y += fmt::format("  - {{name: coefficients, file: \"{}\"}}\n", cf.filename().string());
      continue;
    }
    std::string line = "  - {name: " + c.name;
    const auto& keys = effect_catalogue().at(c.name);
    for (const auto& k : keys) {
      if (c.params.contains(k)) line += fmt::format(", {}: {:.10g}", k, c.params.at(k).get<double>());
    }
    line += "}";
    if (c.name == "temperature" && c.params.contains("t0_c")) {
      line += fmt::format("  # diagnosed t0_c {:.4g} C: the bench profile's t0_c", c.params.at("t0_c").get<double>());
    }
    y += line + "\n";
  }
  write_text_atomic(bench, y);
}

std::filesystem::path emitted_coefficients_path(const std::string& bench_path) {
  const std::filesystem::path bench = std::filesystem::absolute(bench_path);
  return bench.parent_path() / (bench.stem().string() + ".coefficients.json");
}

}  // namespace fpss
