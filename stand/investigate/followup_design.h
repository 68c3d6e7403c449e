// The follow-up run that separates look-alikes or bounds what a recording could not see
// (`fpss-stand design --discriminate/--observe`): moves sized to the bench-time budget, each
// candidate procedure simulated on the bench and judged by calib/diagnosis/followup.h.
#pragma once
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "calib/diagnosis/diagnosis.h"
#include "fixtures/bench.h"
#include "procedures/settings.h"

namespace fpss {

// A follow-up is judged separating when the predicted held-out log-likelihood ratio of every
// ambiguous pair reaches this: a realised log-likelihood ratio is about Gaussian with variance
// twice its mean, so at 16 it exceeds the ambiguity margin (5 in log-likelihood) with 95 %.
inline constexpr double kSeparatingLogLR = 16.0;

struct FollowupRequest {
  nlohmann::ordered_json gap;  // the (joint) diagnosis's GAP.json
  CoefficientSet model;        // the sim model the diagnosis used
  EngineSettings settings;     // the stand's or the emulated bench's
  BenchConfig bench;           // the bench a planned run is simulated on (effects cleared)
  double max_bench_s = 0;      // 0: half the bench time of the recordings behind `gap`
  // Where on the bench clock the planned run starts (drift and temperature run on it). NaN: where
  // the recordings behind `gap` end, on a bench whose clock goes on (a stand, investigate's one
  // emulated bench), or 0 when they ran on their own clocks; 0 for a fresh emulated bench.
  double start_s = std::numeric_limits<double>::quiet_NaN();
  bool discriminate = true;    // separate the ambiguous sets
  bool observe = false;        // bound the unbounded candidates below the materiality
  std::string name = "followup";
};

struct PairPrediction {
  std::string a, b;
  double expected_log_lr = 0;  // held-out rows of the planned run
  bool separated = false;
};
struct BoundPrediction {
  std::string name;
  double limit_arcsec = 0;  // the joint limit_arcsec the plan would give
  bool bounded = false;
};

struct FollowupDesign {
  bool found = false;  // the plan separates every pair and bounds every candidate it was asked to
  bool useful = false; // it separates or bounds one, or makes one the recordings could not see visible
  std::string procedure_text;
  std::vector<std::string> moves;
  double bench_s = 0, budget_s = 0, first_bench_s = 0;
  double materiality_arcsec = 0;
  std::vector<PairPrediction> pairs;
  std::vector<BoundPrediction> bounds;
  std::vector<std::string> unreachable;  // asked for, but no move of the stand's can help
  // A refitted transfer function was to be measured over the calibrated range (named or ambiguous
  // over part of it): the plan's rows reach every sixth the recordings missed.
  bool range_asked = false, range_measured = false;
  nlohmann::ordered_json to_json() const;
};

// Throws InputError for a GAP.json without what the design needs.
FollowupDesign design_followup(const FollowupRequest& r);

// The emulated bench's motion and frame rate as a stand's settings (the follow-up's bench when no
// stand file is given).
EngineSettings emulated_settings(const BenchConfig& bench);

// The bench a follow-up is planned on: a stand file's motion and frame rate on the default
// simulated bench, or (no stand file) the emulated bench of `bench_file` (default when empty).
struct FollowupBench {
  EngineSettings settings;
  BenchConfig bench;
};
FollowupBench followup_bench(const std::string& stand_file, const std::string& bench_file);

// Fills each ambiguous set's best_followup: the designer's follow-up for that set alone on this
// bench (moves, predicted log-likelihood ratios, bench time against half the recorded time).
void predict_best_followups(Diagnosis& d, const CoefficientSet& model, const EngineSettings& settings,
                            const BenchConfig& bench);
// The same on the default emulated bench (what `diagnose` writes; `design` predicts for a stand).
void predict_best_followups(Diagnosis& d, const CoefficientSet& model);

// Where a follow-up of the recordings behind a GAP.json starts on their clock: the last one's end
// when they share the bench's clock, else 0.
double followup_start_s(const nlohmann::ordered_json& gap);

// The recorded bench time behind a GAP.json: the sum of its recordings' time spans.
double recorded_bench_s(const nlohmann::ordered_json& gap);

}  // namespace fpss
