// Inside the diagnosis: the recording as per-row features (residuals, motion, approach, settling
// clock, split) and the candidate effects' forward models with their least-squares fits.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/diagnosis/diagnosis.h"

namespace fpss::diag {

// A missing value in the diagnosis's arrays and results.
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

enum class StepKind : uint8_t { dwell, motion };
enum class Use : uint8_t { excluded, fit, heldout };

struct Step {
  int64_t id = 0;
  size_t begin = 0, end = 0;  // rows [begin, end)
  StepKind kind = StepKind::dwell;
  bool heldout = false;
  bool moves[2] = {false, false};  // motion steps: which axes move
};

// Per-row arrays, index 0 pitch (alpha), 1 yaw (beta). Angles arcsec, times s. Column-major and
// lean (about 77 bytes a row): what needs full precision (time, reference, counts, residual) is
// double, derived features (rates, clocks, temperature) float.
struct Recording {
  std::string origin;
  size_t n = 0;
  std::vector<JointPart> parts;  // a joint diagnosis's recordings
  std::vector<double> t;
  std::vector<double> ref[2];
  std::vector<float> counts[2];  // for the transfer-function refit (whole counts are exact in float)
  std::vector<double> res[2];    // model(counts) - ref, from the recorded counts
  std::vector<float> temp;      // temperature_c, NaN when absent
  bool has_temperature = false;
  bool has_since_move = false;    // the recording had a time_since_move_s column
  bool has_approach = false;      // ... and approach_pitch/approach_yaw (the side of each dwell)
  std::vector<uint32_t> step_of;  // index into steps
  std::vector<Step> steps;
  std::vector<float> vel[2];        // reference rate, arcsec/s (0 in dwells)
  std::vector<int8_t> dir[2];       // backlash: the axis's direction of motion at this row (0 before any)
  std::vector<int8_t> move_dir[2];  // settling: direction of the axis in the last move, 0 if it did not move
  std::vector<float> since_move;    // s since the last arrival; NaN while moving
  double meas(int a, size_t i) const { return res[a][i] + ref[a][i]; }  // model(counts)
  std::vector<Use> use;
  // Isolated frames far from their step (calib/outliers.h): kept out of every fit and score.
  std::vector<bool> outlier;
  std::vector<uint8_t> outlier_axes;  // which axes flagged it: 1 pitch (alpha), 2 yaw (beta)
  // The row shares the reference reading of the row before it in its step (same_reading,
  // calib/samples.h): their difference holds the sensor's noise alone, not the reference's.
  std::vector<bool> shared_reading;
  std::vector<bool> turning;  // the two rows around a reversal inside a step (left out)
  size_t outliers = 0;
  size_t outliers_axis[2] = {0, 0};  // frames flagged on pitch (alpha), on yaw (beta)
  std::vector<int64_t> outlier_steps;
  // The reduction's count of the null and offset dwells' outlier frames (calib/reduction.h), and
  // while preparing its flags per row and which rows are dwell frames.
  OutlierSummary dwell_outliers;
  std::vector<OutlierAxes> dwell_flags;
  std::vector<bool> in_dwell;
  double expected_scatter = std::numeric_limits<double>::quiet_NaN();  // model file's, arcsec
  std::vector<uint32_t> fit_rows, heldout_rows;
  CoefficientSet model;
  double guard_s = 0;
  double calibrated_range_arcsec = 1512;  // DiagnosisOptions'
  double arrival_guard_s = 0;             // DiagnosisOptions'
  double departure_guard_s = 0;           // before a dwell's last row (0 until a leading sensor is found)
  size_t arriving_rows = 0, departing_rows = 0;  // dwell rows within the guards (not used)
  double reverse_arcsec = 0;  // the direction detector's hysteresis
  size_t dwells = 0, motions = 0, excluded_rows = 0;
  size_t beyond_fit_rows = 0;  // held-out rows at angles the fit rows do not reach (not judged)
};

// Builds the features from the columns (taken over: the recording is not copied). Throws
// InputError/DataError when the data cannot be used at all.
Recording prepare(DiagnosisColumns&& data, const CoefficientSet& model, const DiagnosisOptions& opts);
// The guards widened (a time skew found longer than the arrival guard, or a sensor found ahead of
// the reference): the dwell frames now inside them are no outliers and no part of any fit or
// score; the split is made again.
void widen_move_guards(Recording& r, const DiagnosisOptions& opts, double arrival_s, double departure_s);

// A dwell row within the arrival guard of its arrival: a lagging sensor may still see the move.
inline bool arriving(const Recording& r, size_t i) {
  return std::isfinite(r.since_move[i]) && r.since_move[i] < r.arrival_guard_s;
}
// A dwell row within the departure guard of the dwell's last row: a leading sensor may already see
// the next move.
inline bool departing(const Recording& r, size_t i) {
  const Step& s = r.steps[r.step_of[i]];
  return s.kind == StepKind::dwell && r.t[s.end - 1] - r.t[i] < r.departure_guard_s;
}
inline bool near_move(const Recording& r, size_t i) { return arriving(r, i) || departing(r, i); }

// The sixths of the calibrated range the usable rows (fit and held out) reach. A row on a boundary
// counts for the sixth above it (the top end for the last).
RangeSections range_sections(const Recording& r);

// The residual (meas - ref) an effect adds, per axis and row, arcsec. Float: a contribution is a
// small correction (float's 1e-7 relative is far below any noise), and a joint fit holds several.
// A column (Candidate::columns) may leave an axis empty: zero there.
struct Contribution {
  std::vector<float> v[2];
  void resize(size_t n) { v[0].assign(n, 0.0f); v[1].assign(n, 0.0f); }
  float at(int a, size_t i) const { return v[a].empty() ? 0.0f : v[a][i]; }
};

// One candidate: its forward model and its fit. `target` is what the effect should explain
// (the residual, or the residual less other effects during a joint fit).
class Candidate {
 public:
  virtual ~Candidate() = default;
  virtual std::string name() const = 0;
  virtual int parameters() const = 0;
  virtual void fit(const Recording& r, const Contribution& target, const std::vector<uint32_t>& rows) = 0;
  // Writes the effect's contribution for every row (0 where the effect says nothing).
  virtual void contribute(const Recording& r, Contribution& out) const = 0;
  virtual nlohmann::ordered_json params() const = 0;
  // Sets parameters from the emulator's names (forward-model use and tests).
  virtual void set(const EffectParams& p) = 0;
  virtual std::unique_ptr<Candidate> clone() const = 0;
  virtual nlohmann::ordered_json notes() const { return nlohmann::ordered_json::object(); }
  // The contribution as a linear combination of columns, any nonlinear parameter held (settling's
  // tau, temperature's T0), so that two effects can be solved jointly by one least-squares
  // problem (alternating fits converge slowly when two effects are correlated, e.g. a bias and a
  // drift). The number of columns, 0 for effects without such a form (time_skew, coefficients).
  virtual int columns() const { return 0; }
  // The columns' values at row i on axis a, written to v[0..columns()). Evaluated row by row
  // where they are summed: a joint fit holds no column arrays (8 bytes a row each).
  virtual void column_values(const Recording& r, size_t i, int a, double* v) const {}
  // A part of the contribution that does not scale with the weights (the contribution is this plus
  // the weighted columns): 0 but for an effect that replaces what the model says (coefficients).
  virtual double column_offset(const Recording& r, size_t i, int a) const { return 0.0; }
  // Sets the column weights (as many as columns() says).
  virtual void set_linear(const std::vector<double>& w) {}
  // Holds a parameter at a value in later fits (a degeneracy resolved by convention).
  virtual void hold(const std::string& key, double value) {}
  // The next fit starts afresh (global search) instead of from the last solution.
  virtual void restart() {}
  // Why the last fit is ill-conditioned or physically implausible (empty when it is not): such a
  // candidate is reported but can never be the cause.
  virtual std::string degenerate() const { return {}; }
};

// The part every candidate writes alike: its name and parameter count, and a copy of its own type.
template <typename Self>
class NamedCandidate : public Candidate {
 public:
  NamedCandidate(const char* name, int parameters) : name_(name), parameters_(parameters) {}
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<Self>(static_cast<const Self&>(*this)); }
  std::string name() const override { return name_; }
  int parameters() const override { return parameters_; }

 private:
  const char* name_;
  int parameters_;
};

std::unique_ptr<Candidate> make_candidate(const std::string& name);
// The refitted transfer function, which lives in its own file for its size.
std::unique_ptr<Candidate> make_coefficients_candidate();

// Hands a column's memory back. `v = {}` does not: it picks the initializer-list assignment,
// which empties the vector and keeps its capacity (at 1M rows the recorded counts and steps
// stayed, 23 MB).
template <typename T>
void release(std::vector<T>& v) {
  std::vector<T>().swap(v);
}

// Scalar minimisation on [lo, hi]: a grid of `steps` points (the objective may have several
// minima), then golden section in the bracket around the best node.
template <typename F>
double minimise_1d(F&& f, double lo, double hi, int steps, double tol) {
  double best_x = lo, best_f = f(lo);
  const double dx = (hi - lo) / steps;
  for (int i = 1; i <= steps; ++i) {
    const double x = lo + dx * i, v = f(x);
    if (v < best_f) { best_f = v; best_x = x; }
  }
  double a = std::max(lo, best_x - dx), b = std::min(hi, best_x + dx);
  constexpr double g = 0.6180339887498949;
  double c = b - g * (b - a), d = a + g * (b - a), fc = f(c), fd = f(d);
  while (b - a > tol) {
    if (fc < fd) { b = d; d = c; fd = fc; c = b - g * (b - a); fc = f(c); }
    else { a = c; c = d; fc = fd; d = a + g * (b - a); fd = f(d); }
  }
  const double x = 0.5 * (a + b);
  return f(x) <= best_f ? x : best_x;
}

}  // namespace fpss::diag
