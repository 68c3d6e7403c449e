// What a recording cannot show: each candidate effect whose signature the recording's coverage
// (offsets, motion while sampling, approach sides, time after arrival, temperature) cannot carry.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "calib/diagnosis/internal.h"
#include "calib/diagnosis/model.h"

namespace fpss::diag {

namespace {


// How a recording's temperature readings sit against time, one reading per step (the engine reads
// the temperature once per point, so a step's rows share its reading: the per-row hold is not a
// departure from time). A reading quantised to q departs from any line by about q / sqrt(12) RMS
// however the true temperature runs, so a departure within twice that says nothing a drift could
// not: the temperature follows time as far as the readings can tell.
struct TemperatureVsTime {
  double span_c = 0, rho = 0, off_line_rms_c = 0, quantum_c = 0;
  double rounding_rms_c() const { return quantum_c / std::sqrt(12.0); }
  bool follows_time() const { return std::abs(rho) > 0.995 || off_line_rms_c <= 2.0 * rounding_rms_c(); }
};

TemperatureVsTime temperature_vs_time(const Recording& r) {
  std::vector<std::pair<double, double>> tT;  // (time of the step's first row, its reading)
  tT.reserve(r.steps.size());
  for (const auto& s : r.steps) {
    if (s.end > s.begin && std::isfinite(r.temp[s.begin])) tT.emplace_back(r.t[s.begin], r.temp[s.begin]);
  }
  TemperatureVsTime out;
  if (tT.size() < 3) return out;
  double n = 0, st = 0, sT = 0, stt = 0, sTT = 0, stT = 0;
  for (const auto& [t, T] : tT) { n += 1; st += t; sT += T; stt += t * t; sTT += T * T; stT += t * T; }
  const double vt = stt - st * st / n, vT = sTT - sT * sT / n, c = stT - st * sT / n;
  out.rho = vt > 0 && vT > 0 ? c / std::sqrt(vt * vT) : 0.0;
  // What the best line in time leaves: vT (1 - rho^2) over the readings.
  out.off_line_rms_c = std::sqrt(std::max(0.0, vT * (1.0 - out.rho * out.rho)) / n);
  std::vector<double> levels;
  levels.reserve(tT.size());
  for (const auto& p : tT) levels.push_back(p.second);
  std::sort(levels.begin(), levels.end());
  out.span_c = levels.back() - levels.front();
  out.quantum_c = std::numeric_limits<double>::infinity();
  for (size_t i = 1; i < levels.size(); ++i) {
    if (const double d = levels[i] - levels[i - 1]; d > 1e-9) out.quantum_c = std::min(out.quantum_c, d);
  }
  if (!std::isfinite(out.quantum_c)) out.quantum_c = 0;
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
                    "{:.4f} C RMS, against {:.4f} C from its reading's {:.3g} C steps): a temperature coefficient "
                    "cannot be told apart from drift, which stands for both; vary the temperature non-monotonically",
                    tt.rho, tt.off_line_rms_c, tt.rounding_rms_c(), tt.quantum_c),
        false);
  }
  return o;
}

}  // namespace fpss::diag
