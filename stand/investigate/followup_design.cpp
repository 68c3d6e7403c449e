// The follow-up designer (stand/investigate/followup_design.h).
#include "stand/investigate/followup_design.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "base/errors.h"
#include "calib/diagnosis/diagnosis.h"
#include "calib/diagnosis/followup.h"
#include "procedures/plan.h"
#include "procedures/procedure.h"
#include "stand/config/stand_config.h"
#include "stand/investigate/plan_session.h"

namespace fpss {
namespace {

using ojson = nlohmann::ordered_json;

constexpr double kOvershootArcsec = 300.0;  // an approach starts this far before its point
constexpr int kFrames = 25;                 // frames of a dwell (sim_to_real's)

// One kind of measurement the designer can add, at one size, as procedure steps.
struct Move {
  std::string name;
  std::string yaml;
};

std::string num(double v) { return fmt::format("{:.6g}", v); }

std::string move_to(double p, double y) {
  return fmt::format("  - move: {{pitch_arcsec: {}, yaw_arcsec: {}}}\n", num(p), num(y));
}

// The points the designer approaches, most telling first: both ends of each axis, then halfway;
// far enough inside the range that the dwell where an approach starts is inside it too (a frame
// beyond the sensor's field is no sample, and the side would go unrecorded).
std::vector<std::pair<double, double>> points(int n, double extent) {
  const double e = extent - kOvershootArcsec, h = e / 2;
  const std::vector<std::pair<double, double>> all = {{e, 0}, {-e, 0}, {0, e}, {0, -e}, {h, 0}, {0, h}, {-h, 0}, {0, -h}};
  return {all.begin(), all.begin() + std::min<size_t>(n, all.size())};
}

// Each point approached from below and from above on both axes, a dwell from arrival. The
// recording holds only dwells and slews: a short dwell where each approach starts records the
// side it comes from (the diagnosis reads directions from the recorded reference).
Move approach_both(int n, double extent) {
  std::string y;
  const std::string mark = "  - sample: {frames: 5}\n";
  for (auto [p, w] : points(n, extent)) {
    for (double side : {-1.0, 1.0}) {
      y += move_to(p + side * kOvershootArcsec, w + side * kOvershootArcsec) + mark + move_to(p, w) +
           fmt::format("  - sample: {{frames: {}}}\n", kFrames);
    }
  }
  return {fmt::format("approaches from both sides at {} points", n), y};
}

// Long dwells from arrival, at points reached across the whole range (so both sides alternate).
Move long_dwells(int n, double duration_s, double extent) {
  std::string y;
  const std::vector<std::pair<double, double>> at = {{extent / 2, 0}, {-extent / 2, 0}, {0, extent / 2}, {0, -extent / 2}};
  for (int k = 0; k < n; ++k) {
    const auto [p, w] = at[k % at.size()];
    y += move_to(p, w) + fmt::format("  - sample: {{duration_s: {}}}\n", num(duration_s));
  }
  return {fmt::format("{} dwells of {} s from arrival", n, num(duration_s)), y};
}

// Continuous slews on both axes at several rates: each segment goes out and back (one reversal),
// so both directions of motion are in it.
Move slews(const std::vector<double>& rates, double period_s, double amplitude_arcsec) {
  std::string y;
  std::vector<std::string> r;
  for (double v : rates) r.push_back(num(v));
  for (const char* axis : {"pitch", "yaw"}) {
    y += fmt::format(
        "  - continuous_slew: {{axis: {}, amplitude_arcsec: {}, rates_arcsec_s: [{}], directions: positive, reversals: 1, "
        "sample_period_s: {}, settle_s: 0.5}}\n",
        axis, num(amplitude_arcsec), fmt::join(r, ", "), num(period_s));
  }
  return {fmt::format("slews on both axes over +-{} arcsec at {} arcsec/s", num(amplitude_arcsec), fmt::join(r, ", ")), y};
}

// Null dwells repeated over time.
Move repeated_nulls(int n, double gap_s) {
  std::string y;
  for (int k = 0; k < n; ++k) {
    if (k) y += fmt::format("  - settle: {{duration_s: {}}}\n", num(gap_s));
    y += move_to(0, 0) + fmt::format("  - sample: {{frames: {}}}\n", kFrames);
  }
  return {fmt::format("{} null dwells {} s apart", n, num(gap_s)), y};
}

// Offsets swept across the whole range along each axis, `n` points an axis, short dwells: a
// transfer function's shape where a narrow recording saw none, at the least bench time (no null
// between offsets).
Move range_sweep(int n, int frames, double extent) {
  std::string y;
  for (int axis = 0; axis < 2; ++axis) {
    for (int k = 0; k < n; ++k) {
      const double o = -extent + 2 * extent * (k + 0.5) / n;  // one a section at n = 6
      y += move_to(axis == 0 ? o : 0, axis == 1 ? o : 0) + fmt::format("  - sample: {{frames: {}, settle_s: 0.2}}\n", frames);
    }
  }
  return {fmt::format("offsets across +-{} arcsec on each axis at {} points, {} frames a dwell", num(extent), n,
                      frames),
          y};
}

// The null-offset grid over the whole range on both axes at the paper's finer step.
Move fine_grid(double step_arcsec, double extent) {
  return {fmt::format("null-offset grid at {} arcsec steps", num(step_arcsec)),
          fmt::format("  - null_offset_grid: {{axes: [pitch, yaw], extent_arcsec: {}, step_arcsec: {}, frames: {}, "
                      "settle_s: 0.2}}\n",
                      num(extent), num(step_arcsec), kFrames)};
}

// `extent`: the calibrated half-range the diagnosis judged a refit over (GAP.json), arcsec.
std::vector<Move> library(const EngineSettings& s, double extent) {
  const double top = std::min(600.0, s.profile_rate_arcsec_s);
  const double period = std::max(0.02, 1.0 / s.sample_rate_hz);
  std::vector<Move> m;
  for (int n : {2, 4, 8}) m.push_back(approach_both(n, extent));
  for (int n : {2, 4}) m.push_back(long_dwells(n, 5.0, extent));
  const double wide = extent - 12;
  m.push_back(slews({top}, period, wide / 2));
  m.push_back(slews({top}, period, wide));
  m.push_back(slews({top / 4, top}, period, wide));
  m.push_back(slews({top / 4, top / 2, top}, period, wide));
  for (int n : {4, 8}) m.push_back(repeated_nulls(n, 30.0));
  m.push_back(range_sweep(6, 5, extent));
  m.push_back(range_sweep(12, 10, extent));
  m.push_back(fine_grid(108.0, extent));
  return m;
}

struct Goal {
  struct Pair {
    EffectParams a, b;
    bool both = true;  // b has fitted params: the smaller of the two directions
    std::vector<std::string> rivals;  // nested: a against these together, one direction only
  };
  std::vector<Pair> pairs;
  std::vector<std::string> bound;  // candidates to bound
  std::vector<double> bound_first;  // their limit_arcsec in the recordings so far (+inf: unseen)
  std::vector<std::string> unreachable;
  // A refitted transfer function to be measured over the whole calibrated range: the sixths the
  // recordings reach so far (pitch, yaw), from its GAP.json notes.
  bool cover = false;
  RangeSections covered{};
};

const ojson* find_effect(const ojson& gap, const std::string& name) {
  if (!gap.contains("effects") || !gap["effects"].is_array()) return nullptr;
  for (const auto& e : gap["effects"]) {
    if (e.is_object() && e.value("name", "") == name) return &e;
  }
  return nullptr;
}

bool is_cause(const ojson& gap, const std::string& name) {
  const ojson& causes = gap.value("causes", ojson::array());
  return causes.is_array() && std::any_of(causes.begin(), causes.end(), [&](const ojson& c) {
           return c.is_object() && c.value("name", "") == name;
         });
}

// The sixths of the range the recordings' rows reach, from the coefficients entry's notes.
void note_coverage(const ojson& gap, Goal& g) {
  g.cover = true;
  const ojson* fc = find_effect(gap, "coefficients");
  const ojson s = fc ? fc->value("notes", ojson::object()).value("range_sections", ojson::object()) : ojson::object();
  for (int a = 0; a < 2; ++a) {
    const ojson& axis = s.value(a == 0 ? "alpha" : "beta", ojson::array());
    for (size_t k = 0; k < g.covered[a].size() && k < axis.size(); ++k) g.covered[a][k] = axis[k] == true;
  }
}

// A refitted transfer function against a simpler member of its set: the refit contains any bias
// and scale, so only one direction can tell, the refit taken as the truth (its prediction beyond
// the rows it was fitted on: the model's sinusoids, changed as the refit found) against the
// simpler explanation, which is the recording's causes together when that member is the cause (a
// bias and a scale factor as a pair). Against a member it does not contain the same one direction
// is used: refitting eq. 1 to every candidate plan's prediction of the other (a Ceres solve per
// plan and pair) is left out, so such a pair's figure is the refit's side only.
void add_nested_pair(const ojson& gap, const std::string& simpler, Goal& g) {
  const ojson* fc = find_effect(gap, "coefficients");
  const EffectParams refit = fc ? effect_from_json(*fc) : EffectParams{};
  if (!refit.coefficients) {
    g.unreachable.push_back(fmt::format("coefficients vs {}: the diagnosis has no refitted transfer function", simpler));
    return;
  }
  Goal::Pair p;
  p.a = refit;
  p.both = false;
  p.rivals = {simpler};
  const ojson& causes = gap.value("causes", ojson::array());
  if (gap.value("cause", "") == simpler && causes.is_array() && causes.size() > 1) {
    p.rivals.clear();
    for (const auto& c : causes) p.rivals.push_back(c.value("name", ""));
  }
  p.b.name = fmt::format("{}", fmt::join(p.rivals, "+"));
  g.pairs.push_back(std::move(p));
  note_coverage(gap, g);  // told apart, the refit must still be measured where it was extrapolated
}

Goal goals(const FollowupRequest& r) {
  Goal g;
  const ojson& gap = r.gap;
  if (r.discriminate && gap.contains("ambiguous") && gap["ambiguous"].is_array()) {
    for (const auto& set : gap["ambiguous"]) {
      const auto& m = set.value("members", ojson::array());
      if (!m.is_array() || m.size() < 2) continue;
      const std::string first = m[0].get<std::string>();
      const ojson* fa = find_effect(gap, first);
      for (size_t k = 1; k < m.size(); ++k) {
        const std::string other = m[k].get<std::string>();
        if (first == "coefficients" || other == "coefficients") {
          add_nested_pair(gap, first == "coefficients" ? other : first, g);
          continue;
        }
        if (!fa) {
          g.unreachable.push_back(fmt::format("{} vs {}: {} has no fitted parameters", first, other, first));
          continue;
        }
        Goal::Pair p;
        p.a = effect_from_json(*fa);
        const ojson* fb = find_effect(gap, other);
        p.both = fb != nullptr;
        if (fb) p.b = effect_from_json(*fb);
        else p.b.name = other;
        g.pairs.push_back(std::move(p));
        // A member the recordings could not score at all (a lag behind dwells only): the figure
        // above says only how well it could mimic the other; the plan must also let it be seen.
        // Not a temperature: the bench's temperature is not the stand's to move.
        if (!fb && other != "temperature" && std::find(g.bound.begin(), g.bound.end(), other) == g.bound.end()) {
          g.bound.push_back(other);
          g.bound_first.push_back(std::numeric_limits<double>::infinity());
        }
      }
    }
  }
  if (r.observe && gap.contains("candidates") && gap["candidates"].is_array()) {
    for (const auto& c : gap["candidates"]) {
      if (c.value("status", "") != "unbounded") continue;
      const std::string name = c.value("name", "");
      const std::string why = c.value("why", "");
      if (name == "temperature" && why.find("no temperature_c") != std::string::npos) {
        g.unreachable.push_back("temperature: the recording has no temperature_c column; no move adds one");
      } else if (name == "temperature" && why.find("not observable") != std::string::npos) {
        g.unreachable.push_back("temperature: " + why + " (the bench's temperature is not the stand's to move)");
      } else if (why.rfind("seen but not named", 0) == 0) {
        g.unreachable.push_back(name + ": " + why + " (a second effect the diagnosis could not pair; more of the same "
                                                    "data, not a new move)");
      } else if (name == "coefficients" && is_cause(gap, name)) {
        note_coverage(gap, g);  // named, but over part of the range only
      } else if (name == "coefficients") {
        g.unreachable.push_back("coefficients: bounded by more offsets over the range (a longer grid), not planned here");
      } else {
        g.bound.push_back(name);
        const auto& l = c.value("limit_arcsec", ojson());
        g.bound_first.push_back(l.is_number() ? l.get<double>() : std::numeric_limits<double>::infinity());
      }
    }
  }
  return g;
}

struct Evaluation {
  bool valid = false;
  double bench_s = 0, gain = 0;
  bool all = false;
  std::string text;
  std::vector<PairPrediction> pairs;
  std::vector<BoundPrediction> bounds;
  bool covered = false;  // the plan measures the refit over the rest of the range
};

std::string procedure_text(const FollowupRequest& r, const std::vector<const Move*>& moves) {
  // A null dwell opens and closes every follow-up: a reference for the slews and a held-out
  // step of each kind even when the moves are slews alone.
  std::string t = fmt::format("name: {}\nsteps:\n  - home\n  - sample: {{frames: {}}}\n", r.name, kFrames);
  for (const Move* m : moves) t += m->yaml;
  return t + move_to(0, 0) + fmt::format("  - sample: {{frames: {}}}\n", kFrames);
}

// `quiet`: the request's bench without its effects (a plan is judged on the candidates' own
// forward models).
Evaluation evaluate(const FollowupRequest& r, const BenchConfig& quiet, const Goal& g,
                    const std::vector<const Move*>& moves, double noise, double materiality) {
  Evaluation e;
  e.text = procedure_text(r, moves);
  Diagnostics d(r.name + ".yaml");
  const Procedure proc = parse_procedure(e.text, r.name + ".yaml", d);
  if (!d.empty()) return e;
  const Plan plan = expand(proc, r.settings, d);
  if (!d.empty() || plan.points == 0) return e;
  e.bench_s = plan.physical_s;
  const SampleTable t = simulate_plan(plan, r.settings, quiet, std::isfinite(r.start_s) ? r.start_s : followup_start_s(r.gap));
  if (t.size() < 10) return e;
  std::optional<PlannedRun> run;
  try {
    run.emplace(DiagnosisColumns::of(t), r.model, DiagnosisOptions{}, noise);
  } catch (const std::exception&) {
    return e;  // a plan the diagnosis cannot read: no use
  }
  e.valid = true;
  e.all = true;
  for (const auto& p : g.pairs) {
    const double lr = !p.rivals.empty() ? run->expected_log_lr(p.a, p.rivals)
                      : p.both        ? run->separation(p.a, p.b)
                                      : run->expected_log_lr(p.a, p.b.name);
    PairPrediction pp{p.a.name, p.b.name, lr};
    pp.separated = pp.expected_log_lr >= kSeparatingLogLR;
    e.all = e.all && pp.separated;
    e.gain += std::min(1.0, pp.expected_log_lr / kSeparatingLogLR);
    e.pairs.push_back(pp);
  }
  for (size_t k = 0; k < g.bound.size(); ++k) {
    // What the recordings so far saw of it and what the plan sees combine as two independent
    // measurements of one magnitude: their limits add in inverse squares.
    const double plan = run->limit_arcsec(g.bound[k], 0), first = g.bound_first[k];
    BoundPrediction b{g.bound[k], 1.0 / std::sqrt(1.0 / (plan * plan) + 1.0 / (first * first))};
    b.bounded = b.limit_arcsec <= materiality;
    e.all = e.all && b.bounded;
    e.gain += std::isfinite(b.limit_arcsec) ? std::min(1.0, materiality / b.limit_arcsec) : 0.0;
    e.bounds.push_back(b);
  }
  if (g.cover) {
    const auto planned = run->range_sections();
    int missing = 0, added = 0;
    for (int a = 0; a < 2; ++a) {
      for (size_t k = 0; k < planned[a].size(); ++k) {
        missing += !g.covered[a][k];
        added += !g.covered[a][k] && planned[a][k];
      }
    }
    e.covered = missing == added;
    e.all = e.all && e.covered;
    e.gain += missing > 0 ? static_cast<double>(added) / missing : 1.0;
  }
  return e;
}

// The calibrated half-range of the diagnosis (GAP.json `calibrated_range_arcsec`; the default for
// a GAP.json of an earlier version).
double calibrated_range_arcsec(const ojson& gap) {
  const ojson& v = gap.value("calibrated_range_arcsec", ojson());
  if (v.is_null()) return DiagnosisOptions{}.calibrated_range_arcsec;
  if (!v.is_number() || !(v.get<double>() >= kMinCalibratedRangeArcsec && v.get<double>() <= kMaxCalibratedRangeArcsec)) {
    throw InputError(fmt::format("the diagnosis's calibrated_range_arcsec must be a number in {:g}..{:g}",
                                 kMinCalibratedRangeArcsec, kMaxCalibratedRangeArcsec));
  }
  return v.get<double>();
}

double number(const ojson& j, const char* key) {
  if (!j.contains(key) || !j[key].is_number()) {
    throw InputError(fmt::format("the diagnosis has no number \"{}\" (a GAP.json of this version is needed)", key));
  }
  return j[key].get<double>();
}

}  // namespace

double followup_start_s(const ojson& gap) {
  if (!gap.contains("recordings") || !gap["recordings"].is_array() || gap["recordings"].empty()) return 0;
  const ojson& last = gap["recordings"].back();
  const std::string own = to_string(JointClock::own);
  if (last.value("clock", own) == own) return 0;
  const ojson span = last.value("time_span_s", ojson::array());
  return span.is_array() && span.size() == 2 && span[1].is_number() ? std::max(0.0, span[1].get<double>()) : 0.0;
}

double recorded_bench_s(const ojson& gap) {
  double s = 0;
  if (gap.contains("recordings") && gap["recordings"].is_array()) {
    for (const auto& p : gap["recordings"]) {
      const auto& span = p.value("time_span_s", ojson::array());
      if (span.is_array() && span.size() == 2 && span[0].is_number() && span[1].is_number()) {
        s += span[1].get<double>() - span[0].get<double>();
      }
    }
  }
  return s;
}

FollowupDesign design_followup(const FollowupRequest& r) {
  FollowupDesign out;
  const double noise = number(r.gap, "noise_floor_arcsec");
  out.materiality_arcsec = number(r.gap, "materiality_arcsec");
  out.first_bench_s = recorded_bench_s(r.gap);
  out.budget_s = r.max_bench_s > 0 ? r.max_bench_s : 0.5 * out.first_bench_s;
  const Goal g = goals(r);
  out.unreachable = g.unreachable;
  if (g.pairs.empty() && g.bound.empty() && !g.cover) return out;

  const double extent = calibrated_range_arcsec(r.gap);
  const std::vector<Move> lib = library(r.settings, extent);
  BenchConfig quiet = r.bench;
  quiet.effects.clear();
  for (auto& u : quiet.sensors) u.effects.clear();
  std::vector<const Move*> chosen;
  Evaluation best;
  best.gain = 0;
  for (int round = 0; round < 4; ++round) {
    std::optional<Evaluation> pick, cheapest_all, cheapest_cover;
    const Move* pick_move = nullptr;
    const Move* all_move = nullptr;
    const Move* cover_move = nullptr;
    double pick_rate = 0;
    for (const Move& m : lib) {
      if (std::find(chosen.begin(), chosen.end(), &m) != chosen.end()) continue;
      std::vector<const Move*> with = chosen;
      with.push_back(&m);
      Evaluation e = evaluate(r, quiet, g, with, noise, out.materiality_arcsec);
      if (!e.valid || e.bench_s > out.budget_s) continue;
      if (e.all && (!cheapest_all || e.bench_s < cheapest_all->bench_s)) {
        cheapest_all = e;
        all_move = &m;
      }
      if (g.cover && !best.covered && e.covered && (!cheapest_cover || e.bench_s < cheapest_cover->bench_s)) {
        cheapest_cover = e;
        cover_move = &m;
      }
      const double rate = (e.gain - best.gain) / std::max(1.0, e.bench_s - best.bench_s);
      if (e.gain > best.gain + 1e-6 && rate > pick_rate) {
        pick_rate = rate;
        pick = e;
        pick_move = &m;
      }
    }
    if (cheapest_all) {
      chosen.push_back(all_move);
      best = *cheapest_all;
      break;
    }
    // A refit extrapolated over most of the range is no measurement, whatever else is bounded:
    // the cheapest move that measures it comes before the rest.
    if (cheapest_cover) {
      chosen.push_back(cover_move);
      best = *cheapest_cover;
      continue;
    }
    if (!pick) break;
    chosen.push_back(pick_move);
    best = *pick;
  }
  if (chosen.empty()) return out;
  // Useful: it separates a pair, bounds a candidate, or lets the diagnosis see one it could not
  // see at all (an effect that is there is then named; one that is not gets a limit).
  out.useful = std::any_of(best.pairs.begin(), best.pairs.end(), [](const PairPrediction& p) { return p.separated; }) ||
               std::any_of(best.bounds.begin(), best.bounds.end(), [](const BoundPrediction& b) { return b.bounded; });
  for (size_t k = 0; k < best.bounds.size(); ++k) {
    out.useful = out.useful || (!std::isfinite(g.bound_first[k]) && std::isfinite(best.bounds[k].limit_arcsec));
  }
  out.useful = out.useful || best.covered;
  out.range_asked = g.cover;
  out.range_measured = best.covered;
  out.found = best.all;
  out.bench_s = best.bench_s;
  out.pairs = best.pairs;
  out.bounds = best.bounds;
  for (const Move* m : chosen) out.moves.push_back(m->name);
  std::string head = fmt::format(
      "# A follow-up designed by `fpss-stand design` from {}: {}.\n# Bench time {:.0f} s of a budget of {:.0f} s (the "
      "recordings so far: {:.0f} s).\n",
      r.gap.value("source", std::string("a diagnosis")), fmt::join(out.moves, "; "), out.bench_s, out.budget_s,
      out.first_bench_s);
  for (const auto& p : out.pairs) {
    head += fmt::format("# {} vs {}: expected log-likelihood ratio {:.1f} on the held-out rows (separating from {:g})\n",
                        p.a, p.b, p.expected_log_lr, kSeparatingLogLR);
  }
  for (const auto& b : out.bounds) {
    head += fmt::format("# {}: would be seen from {:.4f} arcsec where it acts (materiality {:.4f})\n", b.name,
                        b.limit_arcsec, out.materiality_arcsec);
  }
  if (g.cover) {
    head += fmt::format("# coefficients: {} over every sixth of the calibrated range +-{:g} arcsec\n",
                        best.covered ? "measured" : "not measured", extent);
  }
  out.procedure_text = head + best.text;
  return out;
}

EngineSettings emulated_settings(const BenchConfig& bench) {
  EngineSettings s = emulated_stand(1.0).bench;
  s.profile_rate_arcsec_s = bench.max_rate_arcsec_s;
  s.acceleration_arcsec_s2 = bench.accel_arcsec_s2;
  s.sample_rate_hz = bench.sample_rate_hz;
  return s;
}

FollowupBench followup_bench(const std::string& stand_file, const std::string& bench_file) {
  FollowupBench f;
  if (!stand_file.empty()) {
    f.settings = load_stand_file(stand_file).bench;
    f.bench = default_bench_config();
    f.bench.max_rate_arcsec_s = f.settings.profile_rate_arcsec_s;
    f.bench.accel_arcsec_s2 = f.settings.acceleration_arcsec_s2;
    return f;
  }
  f.bench = bench_file.empty() ? default_bench_config() : load_bench_file(bench_file);
  f.settings = emulated_settings(f.bench);
  return f;
}

void predict_best_followups(Diagnosis& d, const CoefficientSet& model, const EngineSettings& settings,
                            const BenchConfig& bench) {
  if (d.ambiguous.empty()) return;
  const ojson gap = d.to_json();
  for (size_t k = 0; k < d.ambiguous.size(); ++k) {
    FollowupRequest r;
    r.gap = gap;
    r.gap["ambiguous"] = ojson::array({gap["ambiguous"][k]});
    r.model = model;
    r.settings = settings;
    r.bench = bench;
    const FollowupDesign f = design_followup(r);
    ojson lr = ojson::object();
    for (const auto& p : f.pairs) lr[p.a + " vs " + p.b] = p.expected_log_lr;
    d.ambiguous[k].best_followup = {{"separates", f.found},
                                    {"moves", f.moves},
                                    {"expected_log_lr", lr},
                                    {"bench_s", f.bench_s},
                                    {"budget_s", f.budget_s},
                                    {"not_planned", f.unreachable},
                                    {"bench", "the default emulated bench unless `fpss-stand design` was given one"}};
  }
}

void predict_best_followups(Diagnosis& d, const CoefficientSet& model) {
  const BenchConfig bench = default_bench_config();
  predict_best_followups(d, model, emulated_settings(bench), bench);
}

ojson FollowupDesign::to_json() const {
  ojson pj = ojson::array();
  for (const auto& p : pairs) {
    pj.push_back({{"a", p.a}, {"b", p.b}, {"expected_log_lr", p.expected_log_lr}, {"separated", p.separated}});
  }
  ojson bj = ojson::array();
  for (const auto& b : bounds) {
    bj.push_back({{"name", b.name},
                  {"limit_arcsec", std::isfinite(b.limit_arcsec) ? ojson(b.limit_arcsec) : ojson()},
                  {"bounded", b.bounded}});
  }
  return {{"found", found},
          {"useful", useful},
          {"moves", moves},
          {"bench_s", bench_s},
          {"budget_s", budget_s},
          {"first_bench_s", first_bench_s},
          {"materiality_arcsec", materiality_arcsec},
          {"separating_log_lr", kSeparatingLogLR},
          {"pairs", pj},
          {"bounds", bj},
          {"unreachable", unreachable},
          {"range", {{"asked", range_asked}, {"measured", range_measured}}}};
}

}  // namespace fpss
