// What a recording cannot show: each candidate effect whose signature the recording's coverage
// (offsets, motion while sampling, approach sides, time after arrival, temperature) cannot carry.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "calib/diagnosis/internal.h"
#include "calib/diagnosis/model.h"

namespace fpss::diag {

namespace {

// How a recording's temperature readings sit against time, one reading per step (the engine reads
// the temperature once per point, so a step's rows share its reading: the hold within a step is
// not a departure from time). The temperature follows time as far as its readings can tell when
// what a straight line in time leaves of them is no more than twice what the readings themselves
// scatter: their rounding (a reading quantised to q departs from any line by about q / sqrt(12)
// RMS however the true temperature runs) and their noise (from the second differences of
// successive readings, which a smooth temperature hardly moves). Scored then, the rough readings
// would lose to a smooth drift by more than the margin: a confident wrong cause. A departure
// above that is the temperature's own shape, which the scores weigh.
struct TemperatureVsTime {
  double span_c = 0, rho = 0, off_line_rms_c = 0, quantum_c = 0, noise_c = 0, level_c = 0;
  double rounding_rms_c() const { return quantum_c / std::sqrt(12.0); }
  // What the readings scatter by themselves, with 1e-6 of their level as the floor (a few ulps of
  // float storage, whose relative step is about 1e-7).
  double reading_rms_c() const {
    return std::max({std::hypot(rounding_rms_c(), noise_c), 1e-6 * std::abs(level_c), 1e-9});
  }
  bool follows_time() const { return off_line_rms_c <= 2.0 * reading_rms_c(); }
};

// The straight line's leftover RMS and the correlation of (x, y) pairs.
std::pair<double, double> line_fit(const std::vector<std::pair<double, double>>& xy) {
  double n = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  for (const auto& [x, y] : xy) { n += 1; sx += x; sy += y; sxx += x * x; syy += y * y; sxy += x * y; }
  const double vx = sxx - sx * sx / n, vy = syy - sy * sy / n, c = sxy - sx * sy / n;
  const double rho = vx > 0 && vy > 0 ? c / std::sqrt(vx * vy) : 0.0;
  return {std::sqrt(std::max(0.0, vy * (1.0 - rho * rho)) / n), rho};
}

// The readings' resolution: the smallest step between distinct readings when every step is a
// whole number of it (to 5 %: float storage), else 0.
double resolution(std::vector<double> levels) {
  std::sort(levels.begin(), levels.end());
  levels.erase(std::unique(levels.begin(), levels.end(), [](double a, double b) { return b - a <= 1e-9; }), levels.end());
  if (levels.size() < 3) return 0;
  double q = std::numeric_limits<double>::infinity();
  for (size_t i = 1; i < levels.size(); ++i) q = std::min(q, levels[i] - levels[i - 1]);
  for (size_t i = 1; i < levels.size(); ++i) {
    const double m = (levels[i] - levels[i - 1]) / q;
    if (std::abs(m - std::round(m)) > 0.05) return 0;
  }
  return q;
}

TemperatureVsTime temperature_vs_time(const Recording& r) {
  TemperatureVsTime out;
  std::vector<std::pair<double, double>> steps;  // (time of the step's first row, its reading), in step order
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (size_t i = 0; i < r.n; ++i) {
    if (std::isfinite(r.temp[i])) { lo = std::min<double>(lo, r.temp[i]); hi = std::max<double>(hi, r.temp[i]); }
  }
  for (const auto& s : r.steps) {
    if (s.end > s.begin && std::isfinite(r.temp[s.begin])) steps.emplace_back(r.t[s.begin], r.temp[s.begin]);
  }
  if (steps.size() < 3) return out;
  out.span_c = hi - lo;
  std::tie(out.off_line_rms_c, out.rho) = line_fit(steps);
  // Second differences of successive readings at uneven times (within a recording: a joint's
  // recordings on their own clocks start again): T_i less the interpolation of its neighbours,
  // whose variance is (1 + w^2 + (1-w)^2) sigma^2 for a reading noise sigma.
  double s2 = 0, n2 = 0;
  for (size_t i = 1; i + 1 < steps.size(); ++i) {
    const double span = steps[i + 1].first - steps[i - 1].first;
    if (!(steps[i - 1].first < steps[i].first && steps[i].first < steps[i + 1].first)) continue;
    const double w = (steps[i].first - steps[i - 1].first) / span;
    const double d = steps[i].second - ((1 - w) * steps[i - 1].second + w * steps[i + 1].second);
    s2 += d * d / (1 + w * w + (1 - w) * (1 - w));
    n2 += 1;
  }
  out.noise_c = n2 > 0 ? std::sqrt(s2 / n2) : 0.0;
  std::vector<double> levels;
  levels.reserve(steps.size());
  for (const auto& p : steps) levels.push_back(p.second);
  out.level_c = levels.front();
  out.quantum_c = resolution(std::move(levels));
  return out;
}

}  // namespace

Observability observability(const Recording& r) {
  Observability o;
  auto add = [&](std::string name, std::string reason, bool incomplete) {
    o.missing.push_back({std::move(name), std::move(reason), incomplete});
  };
  // Angles covered at rest (offsets), per axis.
  double span[2];
  for (int a = 0; a < 2; ++a) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const auto& s : r.steps) {
      if (s.kind != StepKind::dwell) continue;
      for (size_t i = s.begin; i < s.end; ++i) { lo = std::min(lo, r.ref[a][i]); hi = std::max(hi, r.ref[a][i]); }
    }
    span[a] = hi - lo;
  }
  constexpr double kMinSpan = 60.0;  // arcsec
  if (span[0] < kMinSpan && span[1] < kMinSpan) {
    const std::string why = fmt::format(
        "no offsets: every dwell lies within {:.0f} arcsec of one position on both axes, so an angle-proportional "
        "error cannot be told apart from a bias; record null-offset steps on both axes",
        std::max(span[0], span[1]));
    for (const char* e : {"scale_factor", "boresight_roll", "axis_nonorthogonality", "coefficients"}) add(e, why, true);
  } else {
    if (span[0] < kMinSpan) {
      add("axis_nonorthogonality", "no pitch offsets: the yaw error proportional to pitch cannot be seen", true);
    }
    if (span[0] < kMinSpan || span[1] < kMinSpan) {
      add("boresight_roll",
          fmt::format("no {} offsets: a roll cannot be told apart from axis_nonorthogonality or a scale factor",
                      span[0] < kMinSpan ? "pitch" : "yaw"),
          true);
    }
  }
  // Motion while sampling.
  size_t moving = 0;
  for (size_t i = 0; i < r.n; ++i) {
    if (r.use[i] != Use::excluded && (std::abs(r.vel[0][i]) > 5.0 || std::abs(r.vel[1][i]) > 5.0)) ++moving;
  }
  if (moving < 20) {
    add("time_skew",
        "no motion while sampling (no slew rows away from the segment ends): a shift between the sensor's and the "
        "reference's sampling times changes nothing at rest, so it cannot be seen; record continuous slews",
        true);
  }
  // Approach from both sides.
  size_t plus = 0, minus = 0;
  for (uint32_t i : r.fit_rows) for (int a = 0; a < 2; ++a) { plus += r.dir[a][i] > 0; minus += r.dir[a][i] < 0; }
  if (plus < 5 || minus < 5) add("backlash", "every position was approached from the same side: backlash acts as a bias", false);
  // Dwells after moves with a clock since arrival.
  size_t settled = 0;
  double tmin = std::numeric_limits<double>::infinity(), tmax = -tmin;
  for (uint32_t i : r.fit_rows) {
    if (!std::isfinite(r.since_move[i]) || (r.move_dir[0][i] == 0 && r.move_dir[1][i] == 0)) continue;
    ++settled;
    tmin = std::min<double>(tmin, r.since_move[i]);
    tmax = std::max<double>(tmax, r.since_move[i]);
  }
  if (settled < 10 || !(tmax - tmin > 0.02)) {
    add("settling", "no dwell samples spread in time after a move: a decay after arrival cannot be seen", false);
  }
  // Temperature: present, varying, and not a linear function of time (else it is drift).
  if (!r.has_temperature) {
    add("temperature", "the recording has no temperature_c column", false);
  } else if (const TemperatureVsTime tt = temperature_vs_time(r); !(tt.span_c >= 0.05)) {
    add("temperature", fmt::format("temperature_c varies by only {:.3f} C", tt.span_c), false);
  } else if (tt.follows_time()) {
    add("temperature",
        fmt::format("temperature_c follows time linearly (correlation {:.4f}; it leaves a straight line in time by "
                    "{:.4f} C RMS, against {:.4f} C of the readings' own scatter{}): a temperature coefficient "
                    "cannot be told apart from drift, which stands for both; vary the temperature non-monotonically",
                    tt.rho, tt.off_line_rms_c, tt.reading_rms_c(),
                    tt.quantum_c > 0 ? fmt::format(", their {:.3g} C steps among it", tt.quantum_c) : std::string()),
        false);
  }
  return o;
}

}  // namespace fpss::diag
