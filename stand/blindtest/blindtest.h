// The blind check of the diagnosis: random effects on the simulated bench, only the recording and the model handed over.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/diagnosis/diagnosis.h"
#include "fixtures/bench.h"
#include "fixtures/recording.h"

namespace fpss {

// The classes drawn: the ten effects and none.
const std::vector<std::string>& blindtest_classes();

// The session every case records: a null-offset grid on both axes (dwells sampled from 0.2 s
// after arrival, so settling shows) and continuous slews on both axes at 300 and 600 arcsec/s.
SessionPlan blindtest_plan();
// The bench: the default (truth a-6-fpss1, 0.3-count noise, 0.05 arcsec encoder noise) with a
// non-monotonic temperature profile (ramp plus a sinusoid), so temperature and drift differ.
BenchConfig blindtest_bench(uint64_t seed);
// What the diagnosis is told about the recording procedure (not about the effect): when its
// dwells start after arrival.
DiagnosisOptions blindtest_diagnosis_options();

// A random effect of one class with a magnitude clearly above noise but realistic.
// `cls` "none" gives no effect. Deterministic in `seed`.
std::vector<Effect> draw_effects(const std::string& cls, uint64_t seed, const BenchConfig& bench);

// A transfer function aged: each axis's two sinusoids (C3, C6) scaled by 1 + amplitude() and moved
// in phase (C5, C8) by phase_rad(), drawn in the order C3, C5, C6, C8, alpha before beta.
CoefficientSet with_sinusoids_changed(CoefficientSet s, const std::function<double()>& amplitude,
                                      const std::function<double()>& phase_rad);

// RMS over +-max_arcsec of (fitted - true) transfer function, relative to the RMS of (true -
// model): how much of a change of coefficients a refit got wrong.
double coefficient_error(const AxisCoeffs& fitted, const AxisCoeffs& truth, const AxisCoeffs& model, double max_arcsec);

struct BlindCase {
  int index = 0;
  std::string truth;                 // class drawn ("a+b" for a pair)
  nlohmann::ordered_json truth_params = nlohmann::ordered_json::object();
  std::string cause;                 // what the diagnosis said
  std::vector<std::string> causes;
  nlohmann::ordered_json fitted_params = nlohmann::ordered_json::object();
  bool correct = false;
  double param_error = 0;            // largest relative error over the truth's parameters (correct cases)
  nlohmann::ordered_json param_errors = nlohmann::ordered_json::object();
  double gap_before_arcsec = 0, gap_after_arcsec = 0, noise_floor_arcsec = 0;
  double gap_after_all_arcsec = 0;  // with every cause reported
  std::string where;  // the leading factor of `where` (factor/axis)
  size_t rows = 0;
};

struct BlindTestOptions {
  int cases = 22;
  uint64_t seed = 1;
  // When set: each case's recording (case-N.csv), the sim model (model.json), the truth
  // (case-N-truth.json) and the diagnosis (case-N-gap.json) are written there, so a case can be
  // re-run with `fpss-stand diagnose`.
  std::string save_dir;
  // Two different effects per case instead of one (or none); correct when `causes` names both.
  // Pairs one of which a refitted transfer function contains (bias, scale_factor with
  // coefficients) are not drawn: they cannot be told apart by construction.
  bool pairs = false;
};

struct BlindTestReport {
  std::vector<BlindCase> cases;
  bool pairs = false;
  double accuracy() const;                          // top-1, all cases
  double accuracy(const std::string& cls) const;    // top-1 among cases of that truth
  double false_alarm_rate() const;                  // truth none, cause not none
  nlohmann::ordered_json to_json() const;
  std::string to_text() const;                      // confusion matrix and figures
};

// Runs `cases` cases; classes are drawn as shuffled blocks of all eleven, so any 11 consecutive
// cases cover every class. `progress` is called after each case.
BlindTestReport run_blindtest(const BlindTestOptions& opts, const std::function<void(const BlindCase&)>& progress = {});

// One case, for tests: record with `effects`, diagnose, score against the truth.
BlindCase run_blind_case(int index, const std::string& cls, const std::vector<Effect>& effects, uint64_t seed,
                         const std::string& save_dir = {});

// Closing the loop: an emulator bench file (the format `emulate --bench` and load_bench_file
// read) with the model as truth and the diagnosed causes as effects, with their parameters. The
// truth is `model_path` (written relative to the bench file's folder when it lies inside it); a
// refitted transfer function is written next to the bench file as <stem>.coefficients.json and
// named by the coefficients effect's `file`. Catalogued causes only; a temperature's t0_c (the
// profile's starting temperature on the emulator) is noted in a comment.
void write_emitted_bench(const std::string& bench_path, const Diagnosis& d, const std::string& model_path);
// Where write_emitted_bench puts a refitted transfer function: <stem>.coefficients.json beside it.
std::filesystem::path emitted_coefficients_path(const std::string& bench_path);

}  // namespace fpss
