// The recording as the diagnosis sees it: residuals through the model, steps, motion, the
// approach and settling state each row inherits from the moves before it, and the split.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "base/errors.h"
#include "calib/diagnosis/model.h"
#include "calib/outliers.h"
#include "calib/samples.h"
#include "calib/units.h"

namespace fpss::diag {
namespace {

// A step whose reference spans more than this on an axis moved during the step (a slew).
// Encoder noise is ~0.05 arcsec, grid offsets hundreds of arcsec.
constexpr double kMotionSpan_arcsec = 5.0;
// A reversal of an axis's motion (or an unrecorded move between rows) is a change of its
// reference by more than this against its running extreme (at least 10x the reference's noise).
constexpr double kReverse_arcsec = 0.5;

int8_t sign_of(double v) { return v > 0 ? 1 : (v < 0 ? -1 : 0); }

// Whether the reference moved during rows [b, e) on the axis (a slew, not a dwell).
bool moved(const std::vector<double>& ref, size_t b, size_t e) {
  const auto [lo, hi] = std::minmax_element(ref.begin() + static_cast<ptrdiff_t>(b), ref.begin() + static_cast<ptrdiff_t>(e));
  return *hi - *lo > kMotionSpan_arcsec;
}

// Takes the columns over (moved, not copied) and computes the residuals through the model.
void residuals(Recording& r, DiagnosisColumns& data, const CoefficientSet& model) {
  const size_t n = r.n;
  r.t = std::move(data.time_s);
  r.ref[0] = std::move(data.ref_pitch_arcsec);
  r.ref[1] = std::move(data.ref_yaw_arcsec);
  const AxisModel am[2] = {model.alpha_model(), model.beta_model()};
  for (int a = 0; a < 2; ++a) {
    std::vector<double>& counts = a == 0 ? data.counts_alpha : data.counts_beta;
    r.res[a].resize(n);
    for (size_t i = 0; i < n; ++i) {
      r.res[a][i] = am[a].angle_arcsec(counts[i]) - r.ref[a][i];
      if (!std::isfinite(r.res[a][i])) {
        throw DataError(fmt::format("{}: data row {}: the model maps counts_{} = {} to a non-finite angle", r.origin,
                                    i + 1, a == 0 ? "alpha" : "beta", counts[i]));
      }
    }
    r.counts[a].assign(counts.begin(), counts.end());
    release(counts);
  }
  if (!data.temperature_c.empty()) {
    r.temp = std::move(data.temperature_c);
    r.has_temperature = std::any_of(r.temp.begin(), r.temp.end(), [](float v) { return std::isfinite(v); });
  } else {
    r.temp.assign(n, static_cast<float>(kNaN));
  }
}

void find_steps(Recording& r, const std::vector<int64_t>& step) {
  const size_t n = r.n;
  // Steps: consecutive rows with one step id (the reader guarantees steps never decrease).
  r.step_of.resize(n);
  for (size_t i = 0; i < n;) {
    Step s;
    s.id = step[i];
    s.begin = i;
    while (i < n && step[i] == s.id) r.step_of[i++] = static_cast<uint32_t>(r.steps.size());
    s.end = i;
    for (int a = 0; a < 2; ++a) s.moves[a] = moved(r.ref[a], s.begin, s.end);
    s.kind = (s.moves[0] || s.moves[1]) ? StepKind::motion : StepKind::dwell;
    (s.kind == StepKind::dwell ? r.dwells : r.motions)++;
    r.steps.push_back(s);
  }
  if (r.dwells < 2) {
    throw DataError(fmt::format(
        "{}: {} dwell{} (steps at rest): a single position and time cannot tell a bias from drift, scale factor, "
        "roll, non-orthogonality, backlash, settling or the transfer function, and nothing is left to hold out; "
        "record a null-offset grid (several dwells on both axes)",
        r.origin, r.dwells == 0 ? "no" : "only one", r.dwells == 1 ? "" : "s"));
  }
}

void expected_scatter(Recording& r, const CoefficientSet& model) {
  // The sim's expected 1-sigma scatter of one sample about its step mean (optional key).
  if (model.extra.contains("expected_scatter_arcsec")) {
    const auto& v = model.extra["expected_scatter_arcsec"];
    if (!v.is_number() || !(v.get<double>() > 0) || !std::isfinite(v.get<double>())) {
      throw InputError("model: \"expected_scatter_arcsec\" must be a positive number (arcsec)");
    }
    r.expected_scatter = v.get<double>();
  }
}

// The frames of the steps at rest are judged by the recording's one reduction (calib/reduction.h:
// the count outlier rule the calibrator, the report and acceptance apply), so a glitch frame is
// the same finding in GAP.json as in calibration.json. At rest by the reference, not by the phase
// labels, which the diagnosis never trusts (a foreign recorder's may be wrong): the steps at rest
// go to the reduction as dwells, the others as slews.
void reduce_dwells(Recording& r, const DiagnosisColumns& data, const DiagnosisOptions& opts) {
  std::vector<Phase> phase(r.n, Phase::slew);
  for (size_t b = 0; b < r.n;) {
    size_t e = b;
    while (e < r.n && data.step[e] == data.step[b]) ++e;
    if (!moved(data.ref_pitch_arcsec, b, e) && !moved(data.ref_yaw_arcsec, b, e)) {
      std::fill(phase.begin() + static_cast<ptrdiff_t>(b), phase.begin() + static_cast<ptrdiff_t>(e), Phase::offset);
    }
    b = e;
  }
  Reduction red = reduce(FrameColumns{r.origin, data.time_s, phase, data.step, data.ref_pitch_arcsec,
                                      data.ref_yaw_arcsec, data.counts_alpha, data.counts_beta},
                         opts.reduction);
  r.dwell_outliers = red.outliers;
  r.dwell_flags = std::move(red.flags);
  r.in_dwell.assign(r.n, false);
  for (size_t i = 0; i < r.n; ++i) r.in_dwell[i] = phase[i] == Phase::offset;
}

void count_outliers(Recording& r) {
  r.outliers = 0;
  r.outliers_axis[0] = r.outliers_axis[1] = 0;
  r.outlier_steps.clear();
  for (size_t i = 0; i < r.n; ++i) {
    if (!r.outlier[i]) continue;
    ++r.outliers;
    for (int a = 0; a < 2; ++a) r.outliers_axis[a] += (r.outlier_axes[i] >> a) & 1;
    const int64_t id = r.steps[r.step_of[i]].id;
    if (r.outlier_steps.empty() || r.outlier_steps.back() != id) r.outlier_steps.push_back(id);
  }
}

void flag_outlier_frames(Recording& r, const CoefficientSet& model, const DiagnosisOptions& opts) {
  const size_t n = r.n;
  // Isolated frames far from a robust local estimate of their step (calib/outliers.h, a running
  // median of 7 frames, so a settling decay or a slew's changing residual is followed): flagged on
  // either axis, they are kept out of every fit, score and noise estimate.
  {
    std::vector<int64_t> ids(n);
    for (size_t i = 0; i < n; ++i) ids[i] = r.steps[r.step_of[i]].id;
    OutlierRule rule;
    rule.local_half_window = 3;
    // Whole counts with little noise can have a zero MAD: the floor is the rounding's own scatter
    // (1/sqrt(12) count) or the expected scatter when the model says it.
    rule.min_sigma = std::isfinite(r.expected_scatter) ? r.expected_scatter
                                                       : rad_to_arcsec(std::abs(model.alpha[1])) / std::sqrt(12.0);
    r.outlier.assign(n, false);
    r.outlier_axes.assign(n, 0);
    // Rows of a slew segment's ends (the guard, below) are not judged: the gimbal's acceleration
    // and a time shift bend the residual there faster than any neighbour median follows.
    std::vector<bool> judged(n, true);
    for (const Step& s : r.steps) {
      if (s.kind == StepKind::dwell) continue;
      for (size_t i = s.begin; i < s.end; ++i) {
        judged[i] = !(r.t[i] - r.t[s.begin] < opts.max_skew_s || r.t[s.end - 1] - r.t[i] < opts.max_skew_s);
      }
    }
    // Frames that share one reference reading (same_reading): the sigma from pairs on different
    // readings (calib/outliers.h).
    r.shared_reading.assign(n, false);
    for (size_t i = 1; i < n; ++i) {
      r.shared_reading[i] =
          ids[i] == ids[i - 1] && same_reading(r.ref[0][i], r.ref[1][i], r.ref[0][i - 1], r.ref[1][i - 1]);
    }
    for (int a = 0; a < 2; ++a) {
      const OutlierFlags f = flag_outliers(r.res[a], ids, rule, r.shared_reading);
      for (size_t i = 0; i < n; ++i) {
        // Dwell frames: the reduction's verdict; slew frames: the running-median rule above.
        // A dwell's frames within the guards of a move are not judged either: a sensor out of step
        // with the reference may still (or already) see the move there (the reduction flags them
        // for the calibration all the same).
        const bool flagged = r.in_dwell[i] ? (i < r.dwell_flags.size() && (a == 0 ? r.dwell_flags[i].alpha
                                                                                   : r.dwell_flags[i].beta))
                                           : f.outlier[i] && judged[i];
        if (!flagged || near_move(r, i)) continue;
        r.outlier[i] = true;
        r.outlier_axes[i] |= static_cast<uint8_t>(1 << a);
      }
    }
    std::vector<OutlierAxes>().swap(r.dwell_flags);
  }
  count_outliers(r);
}

void rates(Recording& r) {
  const size_t n = r.n;
  // Rates within motion steps (central differences); dwells are at rest.
  for (int a = 0; a < 2; ++a) r.vel[a].assign(n, 0.0);
  for (const Step& s : r.steps) {
    if (s.kind != StepKind::motion || s.end - s.begin < 2) continue;
    for (size_t i = s.begin; i < s.end; ++i) {
      const size_t lo = i > s.begin ? i - 1 : i, hi = i + 1 < s.end ? i + 1 : i;
      const double dt = r.t[hi] - r.t[lo];
      for (int a = 0; a < 2; ++a) r.vel[a][i] = dt > 0 && s.moves[a] ? (r.ref[a][hi] - r.ref[a][lo]) / dt : 0.0;
    }
  }
}

void directions(Recording& r, const DiagnosisOptions& opts, const std::vector<float>* approach) {
  const size_t n = r.n;
  // Direction of motion (backlash), per axis and row, from the reference's own motion and
  // never from step boundaries or labels: a hysteresis on the running extreme, `reverse`
  // arcsec wide (far above the reference's noise). A reversal inside a step is dated back to
  // the turning point (the vertex of a parabola through the extreme row and its neighbours);
  // a jump between steps (an unrecorded move) takes effect at the first row after it.
  double ref_noise = 0;
  {
    double s2 = 0;
    size_t m = 0;
    for (const Step& s : r.steps) {
      if (s.kind != StepKind::dwell) continue;
      for (size_t i = s.begin + 1; i + 1 < s.end; ++i) {
        for (int a = 0; a < 2; ++a) {
          const double d = r.ref[a][i + 1] - 2 * r.ref[a][i] + r.ref[a][i - 1];
          s2 += d * d;
          ++m;
        }
      }
    }
    if (m > 10) ref_noise = std::sqrt(s2 / static_cast<double>(m) / 6.0);
  }
  const double reverse = std::max(kReverse_arcsec, 10.0 * ref_noise);
  r.reverse_arcsec = reverse;
  r.turning.assign(n, false);
  for (int a = 0; a < 2; ++a) {
    r.dir[a].assign(n, 0);
    const auto& x = r.ref[a];
    int8_t d = 0;
    size_t hi_i = 0, lo_i = 0;  // the extremes since the last turn
    for (size_t i = 0; i < n; ++i) {
      // A dwell row that says which side its axis came from (the recorder knows every move, those
      // between recorded rows too): that side, and the hysteresis starts again from it.
      if (!approach[a].empty() && r.steps[r.step_of[i]].kind == StepKind::dwell && std::isfinite(approach[a][i]) &&
          approach[a][i] != 0) {
        d = approach[a][i] > 0 ? 1 : -1;
        hi_i = lo_i = i;
        r.dir[a][i] = d;
        continue;
      }
      if (x[i] > x[hi_i]) hi_i = i;
      if (x[i] < x[lo_i]) lo_i = i;
      int8_t turn = 0;
      size_t from = i;
      if (d <= 0 && x[i] - x[lo_i] > reverse) { turn = 1; from = lo_i; }
      else if (d >= 0 && x[hi_i] - x[i] > reverse) { turn = -1; from = hi_i; }
      if (turn != 0) {
        d = turn;
        // Within the step, the turning time is the vertex of the parabola through the extreme
        // row and its neighbours (the gimbal decelerates and reverses at a finite acceleration);
        // rows after it move the new way.
        const Step& st = r.steps[r.step_of[i]];
        if (from > st.begin && from + 1 < st.end && from + 1 <= i) {
          const double t0 = r.t[from - 1], t1 = r.t[from], t2 = r.t[from + 1];
          const double y0 = x[from - 1], y1 = x[from], y2 = x[from + 1];
          const double den = (t0 - t1) * (t0 - t2) * (t1 - t2);
          const double A = (t2 * (y1 - y0) + t1 * (y0 - y2) + t0 * (y2 - y1)) / den;
          const double B = (t2 * t2 * (y0 - y1) + t1 * t1 * (y2 - y0) + t0 * t0 * (y1 - y2)) / den;
          double tv = A != 0 ? -B / (2 * A) : t1;
          if (!std::isfinite(tv)) tv = t1;
          tv = std::clamp(tv, t0, t2);
          for (size_t q = from; q < i; ++q) if (r.t[q] > tv) r.dir[a][q] = d;
          // Rows within max_skew_s of the turn (at least the two around it) are left out of every
          // fit and score, as the slew-segment ends are: a time shift moves where the sensor sees
          // the turn (and a backlash flip with it), and the turning time is known only to a
          // fraction of a sample.
          for (size_t q = st.begin; q < st.end; ++q) {
            if (std::abs(r.t[q] - tv) < std::max(opts.max_skew_s, 1e-9) ||
                (q + 1 < st.end && r.t[q] <= tv && r.t[q + 1] > tv) || (q > st.begin && r.t[q - 1] <= tv && r.t[q] > tv)) {
              r.turning[q] = true;
            }
          }
        }
        hi_i = lo_i = i;
      }
      r.dir[a][i] = d;
    }
  }
}

void settling_clock(Recording& r, std::vector<float>& since_col, const DiagnosisOptions& opts,
                    const std::vector<float>* approach) {
  const size_t n = r.n;
  // Settling clock, as docs/diagnosis.md states the physics: every dwell follows an arrival
  // settle_s before its first row (or time_since_move_s). The axes that ring are those that moved
  // in the last move: that jumped between the previous row and the dwell's first row, or that
  // moved in the motion step just before it; each rings in its own direction of motion. A dwell
  // that continues the previous one (no axis jumped) keeps its clock. Rows of slew segments are
  // moving: no settling.
  for (int a = 0; a < 2; ++a) r.move_dir[a].assign(n, 0);
  // The recording's own time_since_move_s, when it has one, is taken over (NaN kept in motion).
  const bool own = !since_col.empty();
  if (own) r.since_move = std::move(since_col);
  r.has_since_move = own;
  if (!own) r.since_move.assign(n, static_cast<float>(kNaN));
  int8_t ring[2] = {0, 0};
  double arrival = kNaN;
  for (size_t si = 0; si < r.steps.size(); ++si) {
    const Step& s = r.steps[si];
    if (s.kind == StepKind::motion) {
      ring[0] = ring[1] = 0;
      arrival = kNaN;
      if (own) for (size_t i = s.begin; i < s.end; ++i) r.since_move[i] = static_cast<float>(kNaN);
      continue;
    }
    bool moved = false;
    int8_t now[2] = {0, 0};
    if (s.begin > 0) {
      const Step& prev = r.steps[r.step_of[s.begin - 1]];
      for (int a = 0; a < 2; ++a) {
        const double jump = r.ref[a][s.begin] - r.ref[a][s.begin - 1];
        if (std::abs(jump) > r.reverse_arcsec) now[a] = sign_of(jump);
        else if (prev.kind == StepKind::motion && prev.moves[a]) now[a] = r.dir[a][s.begin - 1];
        moved = moved || now[a] != 0;
      }
    }
    // A recorded approach says which axes the last move moved and which way (an approach through
    // an unrecorded overshoot too).
    if (!approach[0].empty() && std::isfinite(approach[0][s.begin]) && std::isfinite(approach[1][s.begin])) {
      for (int a = 0; a < 2; ++a) now[a] = static_cast<int8_t>(approach[a][s.begin]);
      moved = true;
    }
    if (moved || !std::isfinite(arrival)) {
      ring[0] = now[0];
      ring[1] = now[1];
      arrival = r.t[s.begin] - opts.settle_s;
    }
    for (size_t i = s.begin; i < s.end; ++i) {
      for (int a = 0; a < 2; ++a) r.move_dir[a][i] = ring[a];
      if (!own) r.since_move[i] = static_cast<float>(r.t[i] - arrival);
    }
  }
}

// Held-out rows are judged only at angles the fit rows reach, on both axes (to within the
// direction detector's hysteresis, ten times the reference's noise): a score on held-out steps
// measures how well a fitted candidate predicts where it was fitted, not how it extrapolates. A
// stand whose grid is narrower than its slews, with one slew of an axis held out, would otherwise
// judge a refitted transfer function on counts it never saw, where eq. 1's sinusoids (periods
// longer than the field fitted) are free; the physical effects lose only a few rows of evidence.
// `where` judges its angle splines by the same rule.
void judge_within_fit_field(Recording& r) {
  double lo[2], hi[2];
  for (int a = 0; a < 2; ++a) { lo[a] = std::numeric_limits<double>::infinity(); hi[a] = -lo[a]; }
  for (size_t i = 0; i < r.n; ++i) {
    if (r.use[i] != Use::fit) continue;
    for (int a = 0; a < 2; ++a) { lo[a] = std::min(lo[a], r.ref[a][i]); hi[a] = std::max(hi[a], r.ref[a][i]); }
  }
  const double m = r.reverse_arcsec;
  for (size_t i = 0; i < r.n; ++i) {
    if (r.use[i] != Use::heldout) continue;
    for (int a = 0; a < 2; ++a) {
      if (r.ref[a][i] < lo[a] - m || r.ref[a][i] > hi[a] + m) {
        r.use[i] = Use::excluded;
        ++r.beyond_fit_rows;
        break;
      }
    }
  }
}

// The stratum a step is counted in when the split holds one in `heldout_every` out: motions form
// one; dwells four, by the axes they stand off the null on (none, pitch, yaw, both). Counted over
// all dwells at once, a recording's order can put most of one axis's offsets on one side (every
// third step a yaw offset), and the fit rows would then not reach the held-out angles at all.
int split_stratum(const Recording& r, const Step& s) {
  if (s.kind != StepKind::dwell) return 0;
  constexpr double kOffNullArcsec = 5.0;
  int k = 1;
  for (int a = 0; a < 2; ++a) {
    double sum = 0;
    for (size_t i = s.begin; i < s.end; ++i) sum += r.ref[a][i];
    if (std::abs(sum / static_cast<double>(s.end - s.begin)) > kOffNullArcsec) k += 1 << a;
  }
  return k;
}

void split_steps(Recording& r, const DiagnosisOptions& opts) {
  const size_t n = r.n;
  // Split by whole steps: one in `heldout_every` of each stratum is held out (a stratum with two
  // steps gives one to each side); the ends of slew segments are scored by nobody.
  r.guard_s = opts.max_skew_s;
  r.use.assign(n, Use::fit);
  r.fit_rows.clear();
  r.heldout_rows.clear();
  r.excluded_rows = r.beyond_fit_rows = r.arriving_rows = r.departing_rows = 0;
  size_t seen[5] = {0, 0, 0, 0, 0}, total[5] = {0, 0, 0, 0, 0};
  for (const Step& s : r.steps) ++total[split_stratum(r, s)];
  for (Step& s : r.steps) {
    const bool dwell = s.kind == StepKind::dwell;
    const int g = split_stratum(r, s);
    const size_t k = seen[g]++;
    const size_t m = total[g];
    const size_t every = static_cast<size_t>(opts.heldout_every);
    s.heldout = m == 2 ? k == 1 : (m >= 3 && k % every == every - 1);
    for (size_t i = s.begin; i < s.end; ++i) {
      const bool guard = dwell ? near_move(r, i)
                               : r.t[i] - r.t[s.begin] < r.guard_s || r.t[s.end - 1] - r.t[i] < r.guard_s;
      r.arriving_rows += dwell && arriving(r, i);
      r.departing_rows += dwell && departing(r, i);
      r.use[i] = guard || r.outlier[i] || r.turning[i] ? Use::excluded : (s.heldout ? Use::heldout : Use::fit);
    }
  }
  judge_within_fit_field(r);
  for (size_t i = 0; i < n; ++i) {
    if (r.use[i] == Use::fit) r.fit_rows.push_back(static_cast<uint32_t>(i));
    else if (r.use[i] == Use::heldout) r.heldout_rows.push_back(static_cast<uint32_t>(i));
    else ++r.excluded_rows;
  }
  if (r.fit_rows.empty() || r.heldout_rows.empty()) {
    throw DataError(fmt::format("{}: the split by steps left no rows to {}: record more dwells", r.origin,
                                r.fit_rows.empty() ? "fit" : "hold out"));
  }
}

}  // namespace

Recording prepare(DiagnosisColumns&& data, const CoefficientSet& model, const DiagnosisOptions& opts) {
  Recording r;
  r.origin = data.origin.empty() ? std::string("recording") : data.origin;
  r.model = model;
  r.n = data.size();
  r.parts = std::move(data.parts);
  if (r.n == 0) throw DataError(fmt::format("{}: no rows: nothing to diagnose", r.origin));
  if (!(opts.max_skew_s >= 0) || !(opts.settle_s >= 0) || !(opts.arrival_guard_s >= 0) || opts.heldout_every < 2) {
    throw InputError("diagnosis options: max_skew_s, settle_s and arrival_guard_s must be >= 0, heldout_every >= 2");
  }
  const double range = opts.calibrated_range_arcsec;
  if (!(range >= kMinCalibratedRangeArcsec && range <= kMaxCalibratedRangeArcsec)) {
    throw InputError(fmt::format("diagnosis options: calibrated_range_arcsec must lie in {:g}..{:g}",
                                 kMinCalibratedRangeArcsec, kMaxCalibratedRangeArcsec));
  }
  for (const auto* v : {&data.temperature_c, &data.time_since_move_s, &data.approach_pitch, &data.approach_yaw}) {
    if (!v->empty() && v->size() != r.n) throw InputError(fmt::format("{}: an optional column's length differs", r.origin));
  }
  reduce_dwells(r, data, opts);
  residuals(r, data, model);
  find_steps(r, data.step);
  release(data.step);
  expected_scatter(r, model);
  rates(r);
  const std::vector<float> approach[2] = {std::move(data.approach_pitch), std::move(data.approach_yaw)};
  r.has_approach = !approach[0].empty();
  directions(r, opts, approach);
  settling_clock(r, data.time_since_move_s, opts, approach);
  r.calibrated_range_arcsec = opts.calibrated_range_arcsec;
  r.arrival_guard_s = opts.arrival_guard_s;
  flag_outlier_frames(r, model, opts);
  split_steps(r, opts);
  return r;
}

void widen_move_guards(Recording& r, const DiagnosisOptions& opts, double arrival_s, double departure_s) {
  r.arrival_guard_s = arrival_s;
  r.departure_guard_s = departure_s;
  for (size_t i = 0; i < r.n; ++i) {
    if (r.outlier[i] && near_move(r, i)) {
      r.outlier[i] = false;
      r.outlier_axes[i] = 0;
    }
  }
  count_outliers(r);
  split_steps(r, opts);
}

}  // namespace fpss::diag
