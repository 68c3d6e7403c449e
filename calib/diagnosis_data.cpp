// The recording as the diagnosis sees it: residuals through the model, steps, motion, the
// approach and settling state each row inherits from the moves before it, and the split.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "calib/diagnosis_model.h"
#include "calib/errors.h"

namespace fpss::diag {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// A step whose reference spans more than this on an axis moved during the step (a slew).
// Encoder noise is ~0.05 arcsec, grid offsets hundreds of arcsec.
constexpr double kMotionSpan_arcsec = 5.0;
// Between steps, a change of reference larger than this is an (unrecorded) move.
constexpr double kMoveThreshold_arcsec = 1.0;

int8_t sign_of(double v) { return v > 0 ? 1 : (v < 0 ? -1 : 0); }

}  // namespace

Recording prepare(const SampleTable& data, const CoefficientSet& model, const DiagnosisOptions& opts) {
  Recording r;
  r.origin = data.origin.empty() ? std::string("recording") : data.origin;
  r.model = model;
  r.n = data.size();
  if (r.n == 0) throw DataError(fmt::format("{}: no rows: nothing to diagnose", r.origin));
  if (!(opts.max_skew_s >= 0) || !(opts.settle_s >= 0) || opts.heldout_every < 2) {
    throw InputError("diagnosis options: max_skew_s and settle_s must be >= 0, heldout_every >= 2");
  }
  const size_t n = r.n;
  r.t = data.time_s;
  r.ref[0] = data.ref_pitch_arcsec;
  r.ref[1] = data.ref_yaw_arcsec;
  r.counts[0] = data.counts_alpha;
  r.counts[1] = data.counts_beta;
  const AxisModel am[2] = {model.alpha_model(), model.beta_model()};
  for (int a = 0; a < 2; ++a) {
    r.meas[a].resize(n);
    r.res[a].resize(n);
    for (size_t i = 0; i < n; ++i) {
      r.meas[a][i] = am[a].angle_arcsec(r.counts[a][i]);
      r.res[a][i] = r.meas[a][i] - r.ref[a][i];
      if (!std::isfinite(r.res[a][i])) {
        throw DataError(fmt::format("{}: data row {}: the model maps counts_{} = {} to a non-finite angle", r.origin,
                                    i + 1, a == 0 ? "alpha" : "beta", r.counts[a][i]));
      }
    }
  }
  r.temp.assign(n, kNaN);
  if (data.has_column("temperature_c")) {
    r.temp = data.numeric_column("temperature_c");
    r.has_temperature = std::any_of(r.temp.begin(), r.temp.end(), [](double v) { return std::isfinite(v); });
  }
  std::vector<double> since_col;
  if (data.has_column("time_since_move_s")) since_col = data.numeric_column("time_since_move_s");

  // Steps: consecutive rows with one step id (the reader guarantees steps never decrease).
  r.step_of.resize(n);
  for (size_t i = 0; i < n;) {
    Step s;
    s.id = data.step[i];
    s.begin = i;
    while (i < n && data.step[i] == s.id) r.step_of[i++] = static_cast<uint32_t>(r.steps.size());
    s.end = i;
    for (int a = 0; a < 2; ++a) {
      const auto [lo, hi] = std::minmax_element(r.ref[a].begin() + s.begin, r.ref[a].begin() + s.end);
      s.moves[a] = *hi - *lo > kMotionSpan_arcsec;
    }
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

  // Approach and settling state, as the emulator keeps it: each axis remembers the sign of its
  // last motion (backlash) and of its last move (settling, also kept by an axis that did not
  // move); every dwell follows an arrival settle_s before its first row.
  for (int a = 0; a < 2; ++a) {
    r.dir[a].assign(n, 0);
    r.move_dir[a].assign(n, 0);
  }
  r.since_move.assign(n, kNaN);
  int8_t last_dir[2] = {0, 0}, last_move[2] = {0, 0};
  double prev_end[2] = {kNaN, kNaN};
  for (const Step& s : r.steps) {
    for (int a = 0; a < 2; ++a) {
      const double d = r.ref[a][s.begin] - prev_end[a];
      if (std::isfinite(d) && std::abs(d) > kMoveThreshold_arcsec) last_dir[a] = last_move[a] = sign_of(d);
    }
    if (s.kind == StepKind::dwell) {
      const double arrival = r.t[s.begin] - opts.settle_s;
      for (size_t i = s.begin; i < s.end; ++i) {
        for (int a = 0; a < 2; ++a) {
          r.dir[a][i] = last_dir[a];
          r.move_dir[a][i] = last_move[a];
        }
        r.since_move[i] = r.t[i] - arrival;
      }
      for (int a = 0; a < 2; ++a) {
        double sum = 0;
        for (size_t i = s.begin; i < s.end; ++i) sum += r.ref[a][i];
        prev_end[a] = sum / static_cast<double>(s.end - s.begin);
      }
    } else {
      for (int a = 0; a < 2; ++a) {
        if (s.moves[a]) last_dir[a] = last_move[a] = sign_of(r.ref[a][s.end - 1] - r.ref[a][s.begin]);
        for (size_t i = s.begin; i < s.end; ++i) {
          r.dir[a][i] = last_dir[a];
          r.move_dir[a][i] = last_move[a];
        }
        prev_end[a] = r.ref[a][s.end - 1];
      }
    }
    if (!since_col.empty()) {
      for (size_t i = s.begin; i < s.end; ++i) r.since_move[i] = since_col[i];
    }
  }

  // Split by whole steps: one in `heldout_every` of each kind is held out (a kind with two
  // steps gives one to each side); the ends of slew segments are scored by nobody.
  r.guard_s = opts.max_skew_s;
  r.use.assign(n, Use::fit);
  size_t k_dwell = 0, k_motion = 0;
  for (Step& s : r.steps) {
    const bool dwell = s.kind == StepKind::dwell;
    const size_t k = dwell ? k_dwell++ : k_motion++;
    const size_t m = dwell ? r.dwells : r.motions;
    const size_t every = static_cast<size_t>(opts.heldout_every);
    s.heldout = m == 2 ? k == 1 : (m >= 3 && k % every == every - 1);
    for (size_t i = s.begin; i < s.end; ++i) {
      const bool guard = !dwell && (r.t[i] - r.t[s.begin] < r.guard_s || r.t[s.end - 1] - r.t[i] < r.guard_s);
      r.use[i] = guard ? Use::excluded : (s.heldout ? Use::heldout : Use::fit);
    }
  }
  for (size_t i = 0; i < n; ++i) {
    if (r.use[i] == Use::fit) r.fit_rows.push_back(static_cast<uint32_t>(i));
    else if (r.use[i] == Use::heldout) r.heldout_rows.push_back(static_cast<uint32_t>(i));
    else ++r.excluded_rows;
  }
  if (r.fit_rows.empty() || r.heldout_rows.empty()) {
    throw DataError(fmt::format("{}: the split by steps left no rows to {}: record more dwells", r.origin,
                                r.fit_rows.empty() ? "fit" : "hold out"));
  }
  return r;
}

}  // namespace fpss::diag
