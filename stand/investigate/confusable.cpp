// The confusable and unseen cases, investigated on the simulated bench (stand/investigate/confusable.h).
#include "stand/investigate/confusable.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>

#include "base/text_file.h"
#include "calib/samples.h"
#include "fixtures/bench.h"
#include "procedures/procedure.h"
#include "stand/blindtest/blindtest.h"
#include "stand/investigate/followup_design.h"
#include "stand/investigate/investigation.h"
#include "stand/investigate/plan_session.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using ojson = nlohmann::ordered_json;

// The first runs: what a user would have recorded before asking.
const char* kDwellsOnly =
    "name: dwells_only\nsteps:\n  - home\n  - null_offset_grid: {axes: [pitch, yaw], extent_deg: 0.42, step_deg: 0.06, "
    "frames: 25, settle_s: 0.2}\n";

// The same grid sampled from each dwell's arrival: a lagging sensor's first frames see the move.
const char* kDwellsFromArrival =
    "name: dwells_from_arrival\nsteps:\n  - home\n  - null_offset_grid: {axes: [pitch, yaw], extent_deg: 0.42, "
    "step_deg: 0.06, frames: 25, settle_s: 0}\n";

// A narrow grid about the null (±0.05 deg): over it a change of the transfer function is nearly a
// straight line in the angle, which a bias and a scale factor also are.
const char* kNarrowGrid =
    "name: narrow_grid\nsteps:\n  - home\n  - null_offset_grid: {axes: [pitch, yaw], extent_deg: 0.05, step_deg: 0.01, "
    "frames: 25, settle_s: 0.2}\n";

std::string slews_only(const char* rates) {
  std::string t = "name: slews_only\nsteps:\n  - home\n  - sample: {frames: 25}\n";
  for (const char* axis : {"pitch", "yaw"}) {
    t += fmt::format("  - continuous_slew: {{axis: {}, amplitude_arcsec: 1500, rates_arcsec_s: [{}], directions: both, "
                     "reversals: 1, sample_period_s: 0.02, settle_s: 0.5}}\n",
                     axis, rates);
  }
  return t + "  - move: {pitch_arcsec: 0, yaw_arcsec: 0}\n  - sample: {frames: 25}\n";
}

// The paper's offsets swept upwards along each axis: every dwell approached from below (the
// sweep starts with a recorded dwell below its first point, so the recording shows the side).
std::string one_side_grid() {
  // A null dwell first: the side of every later move is then in the recording.
  std::string t = "name: one_side_grid\nsteps:\n  - home\n  - sample: {frames: 5}\n";
  for (int axis = 0; axis < 2; ++axis) {
    auto at = [&](double o, int frames) {
      t += fmt::format("  - move: {{pitch_arcsec: {}, yaw_arcsec: {}}}\n  - sample: {{frames: {}, settle_s: 0.2}}\n",
                       axis == 0 ? o : -300.0, axis == 1 ? o : -300.0, frames);
    };
    at(-1512, 5);
    for (int k = -6; k <= 6; ++k) at(k * 216.0, 25);  // 0.06 deg steps, inside the field
  }
  return t;
}

Effect effect(const std::string& name, std::map<std::string, double> params) { return Effect{name, std::move(params), {}}; }

struct Kind {
  std::string name;
  std::string first;  // procedure text
  bool unambiguous = false;
};

const std::vector<Kind>& kinds() {
  static const std::vector<Kind> k = {
      {"skew_behind_dwells", kDwellsOnly},
      {"skew_dwells_from_arrival", kDwellsFromArrival},
      {"settling_behind_slews", slews_only("300, 600")},
      {"backlash_one_side", one_side_grid()},
      {"settling_one_side", one_side_grid()},
      {"skew_single_rate", slews_only("300")},
      {"backlash_single_rate", slews_only("300")},
      {"temperature_sine_dwells", kDwellsOnly},
      {"coefficients_narrow", kNarrowGrid},
      {"unambiguous", ""},
  };
  return k;
}

// The calibrated range a change of coefficients is judged over (the paper's grid, sim_to_real.yaml's
// ±0.42 deg).
constexpr double kRangeArcsec = 1500;

const std::map<std::string, std::string>& main_keys() {
  static const std::map<std::string, std::string> k = {
      {"bias", "pitch_arcsec"},       {"drift", "pitch_arcsec_per_s"},   {"scale_factor", "pitch_ppm"},
      {"boresight_roll", "roll_arcsec"}, {"axis_nonorthogonality", "skew_arcsec"}, {"backlash", "width_arcsec"},
      {"settling", "amplitude_arcsec"}, {"time_skew", "skew_s"},        {"temperature", "pitch_arcsec_per_c"},
      {"coefficients", "transfer"}};
  return k;
}

// An ageing of the unit's transfer function: both sinusoids of each axis changed by 2-8 % in
// amplitude and 0.02-0.08 rad in phase (the kind of change the paper's Figures 1 and 2 show
// between calibrations), small enough that over the narrow grid it passes for a bias and a scale.
Effect aged_coefficients(const CoefficientSet& model, const std::function<double(double, double)>& mag) {
  Effect e{"coefficients", {}, {}};
  const auto small = [&] { return mag(0.02, 0.08); };
  e.coefficients = with_sinusoids_changed(model, small, small);
  e.coefficients->extra["perturbation"] = "aged";
  return e;
}

// The bench and the hidden effect of one case.
BenchConfig case_bench(const std::string& kind, int index, uint64_t seed, std::string* text) {
  BenchConfig cfg = default_bench_config();
  std::mt19937_64 rng(seed * 7919 + static_cast<uint64_t>(index));
  std::uniform_real_distribution<double> u(0, 1);
  auto mag = [&](double lo, double hi) { return (u(rng) < 0.5 ? -1 : 1) * (lo + (hi - lo) * u(rng)); };
  if (kind == "skew_behind_dwells" || kind == "skew_single_rate") {
    cfg.effects = {effect("time_skew", {{"skew_s", std::abs(mag(0.002, 0.008))}})};  // a latency: the sensor is late
  } else if (kind == "skew_dwells_from_arrival") {
    cfg.effects = {effect("time_skew", {{"skew_s", 0.01 + 0.09 * u(rng)}})};
  } else if (kind == "settling_behind_slews") {
    cfg.effects = {effect("settling", {{"amplitude_arcsec", mag(0.3, 2.0)}, {"tau_s", 0.2 + 1.3 * u(rng)}})};
  } else if (kind == "settling_one_side") {
    // A settling far longer than the dwells: at rest it is nearly a constant of the approach's side.
    cfg.effects = {effect("settling", {{"amplitude_arcsec", mag(1.0, 3.0)}, {"tau_s", 3.0 + 7.0 * u(rng)}})};
  } else if (kind == "backlash_one_side" || kind == "backlash_single_rate") {
    cfg.effects = {effect("backlash", {{"width_arcsec", 1.0 + 2.0 * u(rng)}})};
  } else if (kind == "temperature_sine_dwells") {
    cfg.temperature = {20.0, 0.0, 2.0, 1200.0};
    cfg.effects = {effect("temperature", {{"pitch_arcsec_per_c", 1.0}, {"yaw_arcsec_per_c", 1.0}})};
  } else if (kind == "coefficients_narrow") {
    cfg.effects = {aged_coefficients(cfg.truth, mag)};
  } else {
    static const std::vector<std::string> classes = {"bias",    "drift",    "scale_factor", "boresight_roll",
                                                     "axis_nonorthogonality", "backlash", "settling", "time_skew"};
    cfg.effects = draw_effects(classes[static_cast<size_t>(index) % classes.size()], seed * 131 + index, cfg);
  }
  for (const Kind& k : kinds()) {
    if (k.name == kind) *text = k.first;
  }
  return cfg;
}

ConfusableCase run_case(const std::string& kind, int index, uint64_t seed, const fs::path& work) {
  std::string text;
  const BenchConfig cfg = case_bench(kind, index, seed, &text);
  const fs::path dir = work / fmt::format("{}-{}", kind, index);
  fs::create_directories(dir);
  fs::path first = dir / "first.yaml";
  if (kind == "unambiguous") first = shipped_procedures_dir() / "sim_to_real.yaml";
  else write_text_atomic(first, text);
  InvestigationOptions o;
  o.model = cfg.truth;
  o.model_path = "the bench's truth";
  o.settings = emulated_settings(cfg);
  o.bench = cfg;
  o.out_dir = dir;
  double clock_s = 0;  // one bench: each run starts a minute after the last one ended
  const Investigation inv = investigate(first, o, [&](const fs::path& procedure, int k) {
    BenchConfig run_cfg = cfg;
    run_cfg.seed = seed * 1000 + static_cast<uint64_t>(index) * 10 + static_cast<uint64_t>(k);
    SampleTable t = simulate_procedure(load_procedure(procedure), o.settings, run_cfg, clock_s);
    if (t.size() > 0) clock_s = t.time_s.back() + 60.0;
    InvestigationRun r;
    r.samples = dir / fmt::format("run-{}.csv", k + 1);
    write_samples_csv(r.samples.string(), t);
    r.completed = true;
    return r;
  });
  ConfusableCase c;
  c.kind = kind;
  const Effect& truth = cfg.effects.front();
  c.truth = truth.name;
  for (const auto& [key, v] : truth.params) c.truth_params[key] = v;
  c.main_key = main_keys().at(truth.name);
  if (truth.coefficients) {
    c.truth_params = {{"alpha", truth.coefficients->alpha}, {"beta", truth.coefficients->beta}};
  }
  for (const auto& e : inv.final.causes) {
    c.causes.push_back(e.name);
    if (e.name != c.truth) continue;
    c.named = true;
    c.fitted = e.params;
    if (truth.coefficients) {
      c.main_error = std::max(
          coefficient_error(e.params.at("alpha").get<AxisCoeffs>(), truth.coefficients->alpha, cfg.truth.alpha, kRangeArcsec),
          coefficient_error(e.params.at("beta").get<AxisCoeffs>(), truth.coefficients->beta, cfg.truth.beta, kRangeArcsec));
    } else {
      const double want = truth.params.at(c.main_key);
      const double got = e.params.value(c.main_key, std::nan(""));
      c.main_error = std::abs(got - want) / std::abs(want);
    }
  }
  c.followups = static_cast<int>(inv.runs.size()) - 1;
  c.followup_ratio = inv.first_bench_s > 0 ? inv.followup_bench_s / inv.first_bench_s : 0.0;
  c.stop_reason = inv.stop_reason;
  for (const auto& s : inv.final.ambiguous) {
    std::string m;
    for (const auto& x : s.members) m += (m.empty() ? "" : "/") + x;
    c.still_ambiguous.push_back(m);
  }
  return c;
}

}  // namespace

const std::vector<std::string>& confusable_kinds() {
  static const std::vector<std::string> k = [] {
    std::vector<std::string> v;
    for (const Kind& x : kinds()) v.push_back(x.name);
    return v;
  }();
  return k;
}

ConfusableReport run_confusable_cases(int per_kind, uint64_t seed, const fs::path& work,
                                      const std::function<void(const ConfusableCase&)>& progress,
                                      const std::vector<std::string>& only) {
  for (const std::string& k : only) {
    if (std::find(confusable_kinds().begin(), confusable_kinds().end(), k) == confusable_kinds().end()) {
      throw std::invalid_argument("confusable cases: unknown kind " + k);
    }
  }
  ConfusableReport r;
  for (int i = 0; i < per_kind; ++i) {
    for (const std::string& kind : confusable_kinds()) {
      if (!only.empty() && std::find(only.begin(), only.end(), kind) == only.end()) continue;
      r.cases.push_back(run_case(kind, i, seed, work));
      if (progress) progress(r.cases.back());
    }
  }
  return r;
}

ojson ConfusableReport::summary() const {
  ojson kinds_j = ojson::object();
  double conf = 0, conf_ok = 0, un = 0, un_first = 0, max_ratio = 0, sum_ratio = 0;
  for (const std::string& kind : confusable_kinds()) {
    double n = 0, ok = 0, fu = 0, mr = 0;
    for (const auto& c : cases) {
      if (c.kind != kind) continue;
      n += 1;
      ok += c.success();
      fu += c.followups;
      mr = std::max(mr, c.followup_ratio);
      max_ratio = std::max(max_ratio, c.followup_ratio);
      sum_ratio += c.followup_ratio;
      if (kind == "unambiguous") {
        un += 1;
        un_first += c.followups == 0;
      } else {
        conf += 1;
        conf_ok += c.success();
      }
    }
    if (n > 0) {
      kinds_j[kind] = {{"cases", n}, {"named_within_10_percent", ok / n}, {"mean_followups", fu / n},
                       {"max_followup_ratio", mr}};
    }
  }
  const double all = static_cast<double>(cases.size());
  return {{"cases", cases.size()},
          {"confusable_named_within_10_percent", conf > 0 ? conf_ok / conf : 0.0},
          {"unambiguous_stopped_after_first_run", un > 0 ? un_first / un : 0.0},
          {"max_followup_ratio", max_ratio},
          {"mean_followup_ratio", all > 0 ? sum_ratio / all : 0.0},
          {"targets", {{"confusable_named_within_10_percent", 0.95},
                       {"unambiguous_stopped_after_first_run", 0.95},
                       {"max_followup_ratio", 1.0}}},
          {"kinds", kinds_j}};
}

std::string ConfusableReport::to_text() const {
  std::ostringstream s;
  for (const auto& c : cases) {
    std::string causes;
    for (const auto& x : c.causes) causes += (causes.empty() ? "" : "+") + x;
    std::string amb;
    for (const auto& x : c.still_ambiguous) amb += " " + x;
    s << fmt::format("{:<24} truth {:<22} causes {:<24} {} err {:6.3f} follow-ups {} ({:.2f}x) {}{}{}\n", c.kind, c.truth,
                     causes.empty() ? "none" : causes, c.success() ? "OK  " : "MISS", c.main_error, c.followups,
                     c.followup_ratio, c.stop_reason, amb.empty() ? "" : " ambiguous:", amb);
  }
  s << summary().dump(1) << "\n";
  return s.str();
}

}  // namespace fpss
