// The diagnosis: noise floor, observability, every candidate fitted on the fit steps and scored
// on the held-out steps, a second effect when the first leaves a gap, and where the gap lies.
#include "calib/diagnosis/diagnosis.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <malloc.h>
#include <limits>
#include <map>
#include <numeric>
#include <optional>

#include "base/errors.h"
#include "calib/diagnosis/followup.h"
#include "calib/diagnosis/internal.h"
#include "calib/diagnosis/model.h"
#include "calib/effect_catalogue.h"

namespace fpss {

using ojson = nlohmann::ordered_json;
using diag::Candidate;
using diag::Contribution;
using diag::Recording;
using diag::StepKind;
using diag::Use;
using diag::mean_square;
using diag::penalised;
using diag::Scored;
using diag::why_alike;
using diag::where_of;
using diag::within_step_scatter;
using diag::detection_limit;
using diag::decide_verdict;

const std::vector<std::string>& diagnosis_effect_names() {
  static const std::vector<std::string> k = [] {
    std::vector<std::string> names;
    for (const auto& e : effect_specs()) names.push_back(e.name);
    return names;
  }();
  return k;
}

namespace diag {

double mean_square(const Recording& r, const Contribution* c, const std::vector<uint32_t>& rows) {
  double s = 0;
  for (uint32_t i : rows) {
    for (int a = 0; a < 2; ++a) {
      const double e = r.res[a][i] - (c ? c->v[a][i] : 0.0);
      s += e * e;
    }
  }
  return rows.empty() ? 0.0 : s / (2.0 * static_cast<double>(rows.size()));
}

double penalised(double ms, double ms0, int k, double N) {
  if (ms0 <= 0) return k * std::log(N);
  return N * std::log(std::max(ms, 1e-300) / ms0) + k * std::log(N);
}

}  // namespace diag

namespace {
// Hands freed pages in the middle of the heap back (glibc keeps them otherwise): each phase frees
// large working arrays, and a large recording's peak should be what is live.
void release_free_memory() { malloc_trim(0); }

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Measurement noise from within-step scatter: second differences of the residual between
// consecutive rows of a dwell (var = 6 sigma^2 for white noise; smooth effects such as settling,
// drift or temperature nearly cancel), clipped at 4 sigma to drop the odd step change. Only rows
// on readings of their own: two rows on one reference reading differ by the sensor's noise alone,
// and with most frames of a dwell on one reading (a host that reads the gimbal less often than
// frames come) the floor fell to the sensor's and noise-only recordings showed causes. With
// `settling` (the settling candidate's fitted contribution) the decay inside each dwell is taken
// off first: a fast decay's curvature at a dwell's first frames is not noise, and it raised the
// floor (0.075-0.12 arcsec against a true 0.065) and with it every materiality and detection limit.
double noise_floor(const Recording& r, double* per_axis, const Contribution* settling = nullptr, size_t from = 0,
                   size_t to = std::numeric_limits<size_t>::max()) {
  auto res = [&](int a, size_t i) { return settling ? r.res[a][i] - settling->at(a, i) : r.res[a][i]; };
  // order 2: second differences (var 6 sigma^2), order 1: first differences (var 2 sigma^2).
  auto estimate = [&](StepKind kind, int a, int order, size_t* used) {
    std::vector<double> d2;
    for (const auto& s : r.steps) {
      if (s.kind != kind || s.begin < from || s.end > to) continue;
      for (size_t i = s.begin + 1; i + (order == 2 ? 1 : 0) < s.end; ++i) {
        if (r.outlier[i] || r.outlier[i - 1] || (order == 2 && r.outlier[i + 1])) continue;
        if (near_move(r, i - 1) || near_move(r, i) || (order == 2 && near_move(r, i + 1))) continue;
        if (r.shared_reading[i] || (order == 2 && r.shared_reading[i + 1])) continue;
        const double d = order == 2 ? res(a, i + 1) - 2 * res(a, i) + res(a, i - 1) : res(a, i) - res(a, i - 1);
        d2.push_back(d * d);
      }
    }
    *used = d2.size();
    if (d2.size() < 10) return kNaN;
    double ms = std::accumulate(d2.begin(), d2.end(), 0.0) / static_cast<double>(d2.size());
    for (int it = 0; it < 3; ++it) {
      const double lim = 16.0 * ms;
      double s = 0;
      size_t m = 0;
      for (double v : d2) if (v <= lim) { s += v; ++m; }
      if (m == 0) break;
      ms = s / static_cast<double>(m);
    }
    return std::sqrt(ms / (order == 2 ? 6.0 : 2.0));
  };
  double sig[2];
  for (int a = 0; a < 2; ++a) {
    size_t used = 0;
    sig[a] = estimate(StepKind::dwell, a, 2, &used);
    if (!std::isfinite(sig[a])) sig[a] = estimate(StepKind::motion, a, 2, &used);
    if (!std::isfinite(sig[a])) sig[a] = estimate(StepKind::dwell, a, 1, &used);
    if (per_axis) per_axis[a] = sig[a];
  }
  return std::sqrt(0.5 * (sig[0] * sig[0] + sig[1] * sig[1]));
}

Scored fit_one(const Recording& r, const std::string& name, const Contribution& target, double ms0, double N) {
  Scored s;
  s.cand = diag::make_candidate(name, r);
  s.cand->fit(r, target, r.fit_rows);
  const Contribution c = s.contribution(r);
  s.result.name = name;
  s.result.params = s.cand->params();
  s.result.parameters = s.cand->parameters();
  s.result.fit_rms_arcsec = std::sqrt(mean_square(r, &c, r.fit_rows));
  const double ms = mean_square(r, &c, r.heldout_rows);
  s.result.heldout_rms_arcsec = std::sqrt(ms);
  s.result.score = penalised(ms, ms0, s.result.parameters, N);
  s.result.notes = s.cand->notes();
  s.result.degenerate = s.cand->degenerate();
  return s;
}

// A settling time constant short enough that only the first frames after an arrival show it.
constexpr double kArrivalOnlyTau_s = 0.05;

// The state diagnose's steps share; the steps run in the order their methods are declared.
class Diagnoser {
 public:
  Diagnoser(DiagnosisColumns&& data, const CoefficientSet& model, const DiagnosisOptions& opts)
      : opts_(opts), r(diag::prepare(std::move(data), model, opts)) {}

  Diagnosis run(DiagnosisFigures* figures) {
    select();
    // A sensor found lagging by more than the arrival guard still saw the end of each move in the
    // dwell frames after it, one found ahead of the reference already saw the next move in a
    // dwell's last frames: those frames are left out and the selection made again, once.
    if (const Guards g = skew_guards(); g.arrival_s != r.arrival_guard_s || g.departure_s != r.departure_guard_s) {
      const double arrival_was = r.arrival_guard_s;
      diag::widen_move_guards(r, opts_, g.arrival_s, g.departure_s);
      d = Diagnosis{};
      all.clear();
      combined = Contribution{};
      select();
      d.warnings.push_back(
          g.departure_s > 0
              ? fmt::format("the departure guard was set to {:.3f} s and the diagnosis made again: a sensor ahead of the "
                            "reference by the time skew found already sees the next move in a dwell's frames that close "
                            "to its end",
                            g.departure_s)
              : fmt::format("the arrival guard was widened from {:g} s to {:.3f} s and the diagnosis made again: a sensor "
                            "that lags by the time skew found still sees the end of the move in the dwell frames before "
                            "that",
                            arrival_was, g.arrival_s));
    }
    locate();
    describe();
    judge_candidates();
    warn();
    if (figures) *figures = diag::figures(r, combined);
    return std::move(d);
  }

 private:
  void select() {
    // Each phase frees large working arrays in the middle of the heap; handing those pages back
    // keeps a large recording's peak to what is live (glibc keeps them otherwise).
    release_free_memory();
    fit_singles();
    release_free_memory();
    pick_cause();
    release_free_memory();
    find_ambiguous();
  }
  struct Guards {
    double arrival_s, departure_s;
  };
  Guards skew_guards() const;
  void fit_singles();
  void pick_cause();
  void find_ambiguous();
  void locate();
  void describe();
  void judge_candidates();
  void warn();

  const DiagnosisOptions& opts_;
  Recording r;
  Diagnosis d;
  double sig[2];
  double N = 0, ms0 = 0;
  std::vector<Scored> all;
  Contribution combined;
  ojson flexible;
};

// The guards a named time skew needs: a lag longer than the arrival guard widens it, a lead sets
// the departure guard, each to the skew with a quarter and 5 ms to spare for its error; unchanged
// when no dwell row lies in the part a guard would add.
Diagnoser::Guards Diagnoser::skew_guards() const {
  Guards g{r.arrival_guard_s, r.departure_guard_s};
  double skew = 0;
  for (const auto& c : d.causes) {
    if (c.name == "time_skew") skew = c.params.value("skew_s", 0.0);
  }
  const double want = 1.25 * std::abs(skew) + 0.005;
  for (size_t i = 0; i < r.n; ++i) {
    const diag::Step& s = r.steps[r.step_of[i]];
    if (s.kind != StepKind::dwell) continue;
    if (skew > r.arrival_guard_s && std::isfinite(r.since_move[i]) && r.since_move[i] >= r.arrival_guard_s &&
        r.since_move[i] < want) {
      g.arrival_s = want;
    }
    const double to_end = r.t[s.end - 1] - r.t[i];
    if (skew < 0 && to_end >= r.departure_guard_s && to_end < want) g.departure_s = want;
  }
  return g;
}

void Diagnoser::fit_singles() {
  d.source = r.origin;
  d.calibrated_range_arcsec = r.calibrated_range_arcsec;
  const diag::Observability obs = diag::observability(r);
  d.not_observable = obs.missing;

  N = 2.0 * static_cast<double>(r.heldout_rows.size());
  Contribution target;
  for (int a = 0; a < 2; ++a) target.v[a].assign(r.res[a].begin(), r.res[a].end());
  {
    // The baseline: nothing, or each recording's own level where recordings do not share a clock.
    Scored none;
    none.cand = diag::make_candidate("none", r);
    std::optional<Contribution> c;
    if (none.cand) {
      none.cand->fit(r, target, r.fit_rows);
      c = none.contribution(r);
    }
    const Contribution* k = c ? &*c : nullptr;
    ms0 = mean_square(r, k, r.heldout_rows);
    d.gap_before_arcsec = std::sqrt(ms0);
    none.result.name = "none";
    none.result.params = ojson::object();
    if (none.cand) none.result.notes = none.cand->notes();
    none.result.fit_rms_arcsec = std::sqrt(mean_square(r, k, r.fit_rows));
    none.result.heldout_rms_arcsec = d.gap_before_arcsec;
    none.result.score = 0;
    all.push_back(std::move(none));
  }
  for (const auto& name : diagnosis_effect_names()) {
    if (!obs.ok(name)) continue;
    all.push_back(fit_one(r, name, target, ms0, N));
  }
  // The noise floor of what the fitted settling leaves (the fits do not depend on it; the
  // selection does). Without a settling fit (not observable) the residual itself.
  {
    const auto st = std::find_if(all.begin(), all.end(), [](const Scored& s) { return s.result.name == "settling"; });
    std::optional<Contribution> c;
    if (st != all.end() && st->result.degenerate.empty()) c = st->contribution(r);
    const Contribution* settling = c ? &*c : nullptr;
    d.noise_floor_arcsec = noise_floor(r, sig, settling);
    // Each recording's own floor (its nuisance level): one entry for a single recording.
    const std::vector<JointPart> one{{r.origin, r.n, 0.0, JointClock::recorded}};
    size_t from = 0;
    for (const auto& [origin, rows, shift, clock] : r.parts.empty() ? one : r.parts) {
      Diagnosis::Part p;
      p.source = origin;
      p.rows = rows;
      p.time_shift_s = shift;
      p.clock = clock;
      p.step_offset = static_cast<int64_t>(d.recordings.size()) * (r.parts.empty() ? 0 : kJointStepStride);
      p.time_span_s[0] = r.t[from];
      p.time_span_s[1] = r.t[from + rows - 1];
      double per[2];
      p.noise_floor_arcsec = r.parts.empty() ? d.noise_floor_arcsec : noise_floor(r, per, settling, from, from + rows);
      d.recordings.push_back(p);
      from += rows;
    }
  }
  std::stable_sort(all.begin(), all.end(), [](const Scored& a, const Scored& b) { return a.result.score < b.result.score; });
  for (const auto& s : all) d.effects.push_back(s.result);
}

void Diagnoser::pick_cause() {
  // No noise floor from the data (dwells of one or two samples or reference readings, no
  // slews): the best held-out RMS bounds it from above.
  if (!std::isfinite(d.noise_floor_arcsec)) {
    d.noise_floor_arcsec = all.front().result.heldout_rms_arcsec;
    d.warnings.push_back("dwells with too few samples or reference readings for within-dwell scatter: the noise floor "
                         "is the best candidate's held-out RMS (an upper bound)");
  }
  // The cause: the best-scoring candidate that is also material, i.e. takes at least a tenth of
  // the noise variance off the held-out mean square (with very many rows, a statistically
  // significant but negligible effect would otherwise count); none if no candidate is.
  const double material = 0.1 * d.noise_floor_arcsec * d.noise_floor_arcsec;
  size_t pick = 0;
  for (size_t k = 0; k < all.size(); ++k) {
    const auto& e = all[k].result;
    if (e.name == "none") { pick = k; break; }
    if (!e.degenerate.empty()) continue;  // an ill-conditioned fit is never the cause
    if (ms0 - e.heldout_rms_arcsec * e.heldout_rms_arcsec >= material) { pick = k; break; }
  }
  const Scored& best = all[pick];
  d.cause = best.result.name;
  d.gap_after_arcsec = best.result.heldout_rms_arcsec;
  d.gap_after_all_arcsec = d.gap_after_arcsec;
  if (d.cause != "none") {
    d.causes = {best.result};
    // A second effect when the first leaves a gap above noise. Pairs are sought around a few
    // single effects (the best single may be a flexible stand-in for two simpler ones, e.g. a
    // settling with an endless tau for backlash plus drift): the others are screened on what
    // that one leaves, the three most promising are fitted jointly with it, and the best pair is
    // kept when it beats the best single's score.
    // Also when the cause is the catch-all refitted transfer function: it contains a bias and a
    // scale factor, and two simple effects may explain the same with far fewer parameters.
    // The fit rows count too: the held-out steps may happen to hold little of a second effect (a
    // non-orthogonality shows only at pitch offsets; a held-out yaw slew has none) while the fit
    // rows show it plainly. A pair found so must still win on the held-out rows.
    const double left = std::max(d.gap_after_arcsec, best.result.fit_rms_arcsec);
    if (opts_.second_effect &&
        (left > opts_.second_effect_gap_ratio * d.noise_floor_arcsec || d.cause == "coefficients")) {
      diag::second_effect(r, all, best, ms0, N, material, d, combined);
    }
  }
  // The causes' contribution: the pair's when one was kept, else the cause's (built after the
  // pair search, which needs the memory).
  if (combined.v[0].empty()) combined = all[pick].contribution(r);
}

void Diagnoser::find_ambiguous() {
  // Close competitors of the cause: singles within the margin of its own score, or of the pair's
  // when two causes were kept (causes[1] carries the joint figures), and any single that beats the
  // pair's first member alone (the pair may be a stand-in for it: a settling with an endless tau
  // and a bias for a one-sided backlash).
  if (d.cause == "none") return;
  double cause_score = 0;
  for (const auto& s : all) if (s.result.name == d.cause) cause_score = s.result.score;
  const double pair_score = d.causes.size() > 1 ? d.causes.back().score : cause_score;
  const bool endless_settling = std::any_of(d.causes.begin(), d.causes.end(), [](const EffectResult& c) {
    return c.name == "settling" && c.params.value("tau_s", 0.0) >= 29.0;
  });
  Diagnosis::AmbiguousSet set;
  set.members = {d.cause};
  set.score_differences = {0.0};
  for (const auto& s : all) {
    const std::string& n = s.result.name;
    if (n == "none" || !s.result.degenerate.empty()) continue;
    if (std::any_of(d.causes.begin(), d.causes.end(), [&](const EffectResult& c) { return c.name == n; })) continue;
    const double diff = s.result.score - cause_score;
    const bool close = std::abs(diff) < kAmbiguityMargin || std::abs(s.result.score - pair_score) < kAmbiguityMargin ||
                       (d.causes.size() > 1 && diff < 0) || (endless_settling && n == "backlash");
    if (close) {
      d.ambiguous_with.push_back({n, diff, why_alike(d.cause, n)});
      set.members.push_back(n);
      set.score_differences.push_back(diff);
    }
  }
  // Look-alikes the recording could not score: what stands for them is the cause. A settling that
  // is gone within the first frames after arrival is what a lagging sensor shows there (the end
  // of the move) when no slew can say whether it lags.
  const bool arrival_only = std::any_of(d.causes.begin(), d.causes.end(), [](const EffectResult& c) {
    return c.name == "settling" && c.params.value("tau_s", 1.0) <= kArrivalOnlyTau_s;
  });
  for (const auto& m : d.not_observable) {
    const bool alike = (d.cause == "drift" && m.name == "temperature" && m.reason.find("follows time") != std::string::npos) ||
                       (d.cause == "bias" && m.name == "backlash") || (arrival_only && m.name == "time_skew");
    if (alike) {
      set.members.push_back(m.name);
      set.score_differences.push_back(kNaN);
    }
  }
  if (set.members.size() < 2) return;
  const diag::Separation sep = diag::separation(set.members[0], set.members[1]);
  set.factor = sep.factor;
  set.measurement = sep.measurement;
  set.why = why_alike(set.members[0], set.members[1]);
  d.ambiguous.push_back(std::move(set));
}

void Diagnoser::locate() {
  // Float copies (where and scatter need no more precision; a large recording's memory does).
  {
    const std::vector<float> before[2] = {{r.res[0].begin(), r.res[0].end()}, {r.res[1].begin(), r.res[1].end()}};
    d.where = where_of(r, before, d.noise_floor_arcsec);
  }
  std::vector<float> after[2];
  for (int a = 0; a < 2; ++a) {
    after[a].resize(r.n);
    for (size_t i = 0; i < r.n; ++i) after[a][i] = static_cast<float>(r.res[a][i] - combined.v[a][i]);
  }
  d.where_after = where_of(r, after, d.noise_floor_arcsec, &flexible);

  // Noise is not structure: the within-step scatter of what the causes leave, against what the
  // sim expects of one sample about its step mean.
  d.within_step_scatter_arcsec = within_step_scatter(r, after);
  d.expected_scatter_arcsec = r.expected_scatter;
  d.outliers = static_cast<int64_t>(r.outliers);
  d.outlier_fraction = static_cast<double>(r.outliers) / static_cast<double>(r.n);
  d.outlier_steps = r.outlier_steps;
  d.dwell_outliers = r.dwell_outliers;
  d.outliers_pitch = static_cast<int64_t>(r.outliers_axis[0]);
  d.outliers_yaw = static_cast<int64_t>(r.outliers_axis[1]);
  d.frames = static_cast<int64_t>(r.n);
  for (auto& e : d.effects) {
    e.detection_limit = detection_limit(r, e, d.noise_floor_arcsec, N);
    e.statistical_limit = diag::statistical_limit(r, e, d.noise_floor_arcsec, N, &e.limit_arcsec);
  }
  {
    std::vector<size_t> frames;
    for (const auto& s : r.steps) if (s.kind == StepKind::dwell) frames.push_back(s.end - s.begin);
    double median = 1;
    if (!frames.empty()) {
      std::nth_element(frames.begin(), frames.begin() + frames.size() / 2, frames.end());
      median = static_cast<double>(std::max<size_t>(1, frames[frames.size() / 2]));
    }
    d.materiality_arcsec = opts_.materiality_arcsec > 0 ? opts_.materiality_arcsec : d.noise_floor_arcsec / std::sqrt(median);
  }
  decide_verdict(r, d, flexible);
}

// What the data holds and how it was divided.
void Diagnoser::describe() {
  std::vector<int64_t> held_ids;
  size_t held_d = 0, held_m = 0;
  for (const auto& s : r.steps) {
    if (!s.heldout) continue;
    held_ids.push_back(s.id);
    (s.kind == StepKind::dwell ? held_d : held_m)++;
  }
  d.split = {
      {"method", fmt::format("by whole steps: of the dwells and of the slew segments, each in recording order, the "
                             "last of every {} steps is held out (a kind with two steps gives one to each side); rows "
                             "of one step are never divided",
                             opts_.heldout_every)},
      {"fit_rows", r.fit_rows.size()},
      {"heldout_rows", r.heldout_rows.size()},
      {"excluded_rows", r.excluded_rows},
      {"excluded_why", fmt::format("the first and last {} s of every slew segment (the reference outside a segment "
                                   "is not recorded, so a time shift cannot be predicted there), the rows within the same margin of every reversal inside a step (a time shift moves where the sensor sees the turn), outlier frames, held-out rows at angles beyond those the fit rows reach on either axis (a score judges prediction, not extrapolation; beyond_fit_rows), dwell rows less than {} s after their arrival (a lagging sensor still sees the move there; arriving_rows), and dwell rows less than {} s before their last (a sensor ahead of the reference already sees the next move there; departing_rows)",
                                   r.guard_s, r.arrival_guard_s, r.departure_guard_s)},
      {"beyond_fit_rows", r.beyond_fit_rows},
      {"arriving_rows", r.arriving_rows},
      {"departing_rows", r.departing_rows},
      {"fit_steps", {{"dwells", r.dwells - held_d}, {"slews", r.motions - held_m}}},
      {"heldout_steps", {{"dwells", held_d}, {"slews", held_m}}},
      {"heldout_step_ids", held_ids}};
  double t_lo = r.t.front(), t_hi = r.t.back();
  d.recording = {{"rows", r.n},
                 {"steps", r.steps.size()},
                 {"dwells", r.dwells},
                 {"slew_segments", r.motions},
                 {"time_span_s", {t_lo, t_hi}},
                 {"noise_floor_per_axis_arcsec", {{"pitch", sig[0]}, {"yaw", sig[1]}}},
                 {"temperature_c", r.has_temperature},
                 {"settle_s", opts_.settle_s},
                 {"arrival_times", r.has_since_move ? "recorded" : "assumed settle_s"},
                 {"approach_sides", r.has_approach ? "recorded" : "read from the reference"}};
}

// Every candidate against the end state, with the material magnitudes of this stand's recordings.
void Diagnoser::judge_candidates() {
  d.material_context = {{"materiality_arcsec", d.materiality_arcsec},
                        {"rule", "named: a cause; bounded: not seen (no gap left for it, or its score not beating "
                                 "none's by the ambiguity margin) and limit_arcsec, its RMS where it acts at its "
                                 "statistical limit, at most the materiality; ambiguous: in a set of look-alikes; "
                                 "unbounded: anything else (not observable, seen but not named, or its limit above "
                                 "the materiality)"}};
  d.candidates = ojson::array();
  for (const CandidateStatus& s : candidate_status(d, d.materiality_arcsec)) {
    ojson j{{"name", s.name}, {"status", s.status}};
    if (!s.why.empty()) j["why"] = s.why;
    j["limit_arcsec"] = std::isfinite(s.limit_arcsec) ? ojson(s.limit_arcsec) : ojson();
    d.candidates.push_back(std::move(j));
  }
}

void Diagnoser::warn() {
  if (r.parts.size() > 1 && r.parts.back().clock == JointClock::own) {
    d.warnings.push_back(
        "the recordings share no clock (no gimbal_time_s in every one, or a gimbal clock that went back, and times "
        "as recorded that start again): each runs on its own clock from its time_s = 0 and keeps a level of its own "
        "per axis (where a drift had got to when it started: what went on between runs is not seen)");
  }
  if (r.parts.size() > 1 && !r.has_since_move) {
    d.warnings.push_back("not every recording has a time_since_move_s column: none is used (arrivals assumed settle_s "
                         "before each dwell's first row in all of them)");
  }
  if (!r.has_since_move) {
    d.warnings.push_back(fmt::format(
        "no time_since_move_s column: dwells are taken to start {} s after their arrival (settle_s); settling "
        "amplitudes refer to that arrival",
        opts_.settle_s));
  }
  if (d.cause != "none" && d.gap_after_all_arcsec > 1.5 * d.noise_floor_arcsec) {
    d.warnings.push_back(fmt::format(
        "the cause{} leave{} {:.2f}x the noise floor on the held-out rows: something else is at work too (see "
        "where_after)",
        d.causes.size() > 1 ? "s" : "", d.causes.size() > 1 ? "" : "s", d.gap_after_all_arcsec / d.noise_floor_arcsec));
  }
  for (const auto& m : d.ambiguous_with) {
    d.warnings.push_back(fmt::format("{} scores within {:.1f} of {}: {}", m.name, m.score_difference, d.cause, m.why));
  }
  for (const auto& n : d.not_observable) {
    d.warnings.push_back(fmt::format("{} is not observable in this recording: {}", n.name, n.reason));
  }
}

}  // namespace

Diagnosis diagnose(DiagnosisColumns data, const CoefficientSet& model, const DiagnosisOptions& opts,
                   DiagnosisFigures* figures) {
  return Diagnoser(std::move(data), model, opts).run(figures);
}

Diagnosis diagnose(const SampleTable& data, const CoefficientSet& model, const DiagnosisOptions& opts) {
  return diagnose(DiagnosisColumns::of(data), model, opts);
}

Diagnosis diagnose(std::vector<DiagnosisColumns> recordings, const CoefficientSet& model, const DiagnosisOptions& opts,
                   DiagnosisFigures* figures) {
  return diagnose(join_recordings(std::move(recordings)), model, opts, figures);
}

SensorPrediction predict_sensor(const SampleTable& data, const CoefficientSet& model, const EffectParams& effect,
                                const DiagnosisOptions& opts) {
  const Recording r = diag::prepare(DiagnosisColumns::of(data), model, opts);
  SensorPrediction p;
  p.pitch_arcsec.resize(r.n);
  p.yaw_arcsec.resize(r.n);
  p.predictable.assign(r.n, true);
  for (size_t i = 0; i < r.n; ++i) p.predictable[i] = r.use[i] != Use::excluded;
  if (effect.name == "coefficients") {
    if (!effect.coefficients) throw InputError("predict_sensor: the coefficients effect needs a coefficient set");
    // The sensor's counts come from the effect's transfer function; the model maps them back.
    const AxisModel truth[2] = {effect.coefficients->alpha_model(), effect.coefficients->beta_model()};
    const AxisModel m[2] = {model.alpha_model(), model.beta_model()};
    for (int a = 0; a < 2; ++a) {
      truth[a].check_monotonic();
      auto& out = a == 0 ? p.pitch_arcsec : p.yaw_arcsec;
      for (size_t i = 0; i < r.n; ++i) {
        try {
          out[i] = m[a].angle_arcsec(truth[a].counts_for_angle_unchecked(arcsec_to_rad(r.ref[a][i])));
        } catch (const std::out_of_range&) {
          out[i] = kNaN;
          p.predictable[i] = false;
        }
      }
    }
    return p;
  }
  auto c = diag::make_candidate(effect.name);
  if (!c) throw InputError(fmt::format("predict_sensor: unknown effect \"{}\"", effect.name));
  c->set(effect);
  Contribution k;
  k.resize(r.n);
  c->contribute(r, k);
  for (size_t i = 0; i < r.n; ++i) {
    p.pitch_arcsec[i] = r.ref[0][i] + k.v[0][i];
    p.yaw_arcsec[i] = r.ref[1][i] + k.v[1][i];
  }
  return p;
}

}  // namespace fpss
