#include "calib/design.h"

#include <Eigen/Dense>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

#include "calib/quantisation.h"
#include "calib/refine.h"
#include "calib/residuals.h"
#include "calib/units.h"

namespace fpss {
namespace {

using Vec8 = Eigen::Matrix<double, 8, 1>;
using Mat8 = Eigen::Matrix<double, 8, 8>;
constexpr int kSigmaAngles = 41;

// What one axis needs: the counts at its null, and per candidate angle the count and the dwell's
// information row (gradient over sigma, times its transpose) at a given frames-per-dwell.
struct AxisModelCache {
  AxisCoeffs c{};
  std::vector<double> sigma_counts;  // counts at the listed angles (+-extent)
  Mat8 null_info = Mat8::Zero();     // one null dwell (or a dwell of the other axis's offsets)
  std::vector<Mat8> offset_info;     // per candidate angle

  Mat8 info_at(const DesignInputs& in, double n, int m) const {
    const AxisModel model(c);
    const double slope = rad_to_arcsec(model.slope_rad_per_count(n));
    const double s = in.count_noise_counts;
    double var_counts = s * s / m;
    if (s >= kMinQuantisationNoise) {
      const double h = expected_rounded_slope(n, s);
      var_counts = rounded_counts_variance(n, s) / (m * h * h);
    } else {
      var_counts = 1.0 / 12.0;  // rounding without dither: not averaged away
    }
    const double var = in.ref_noise_arcsec * in.ref_noise_arcsec / m + slope * slope * var_counts;
    const Vec8 g = fit::dwell_gradient(c, n);
    return g * g.transpose() / var;
  }
};

AxisModelCache cache_axis(const DesignInputs& in, const AxisCoeffs& c, const std::vector<double>& angles_deg, int m) {
  AxisModelCache a;
  a.c = c;
  const AxisModel model(c);
  a.null_info = a.info_at(in, model.counts_for_angle(0.0), m);
  for (double deg : angles_deg) a.offset_info.push_back(a.info_at(in, model.counts_for_angle(arcsec_to_rad(deg_to_arcsec(deg))), m));
  for (int i = 0; i < kSigmaAngles; ++i) {
    const double deg = -in.extent_deg + 2 * in.extent_deg * i / (kSigmaAngles - 1);
    a.sigma_counts.push_back(model.counts_for_angle(arcsec_to_rad(deg_to_arcsec(deg))));
  }
  return a;
}

double max_sigma(const AxisModelCache& a, const Mat8& info) {
  const Eigen::LDLT<Mat8> ldlt(info);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-12 * ldlt.vectorD().maxCoeff())) {
    return std::numeric_limits<double>::infinity();
  }
  double worst = 0;
  for (double n : a.sigma_counts) {
    const Vec8 g = fit::dwell_gradient(a.c, n);
    worst = std::max(worst, std::sqrt(std::max(0.0, g.dot(ldlt.solve(g)))));
  }
  return worst;
}

double slew_s(const DesignInputs& in, double deg) {
  const double d = std::abs(deg), v = in.rate_deg_s, a = in.accel_deg_s2;
  return d >= v * v / a ? d / v + v / a : 2 * std::sqrt(d / a);
}

void check(const DesignInputs& in) {
  if (!(in.rate_deg_s > 0 && in.accel_deg_s2 > 0 && in.frame_rate_hz > 0 && in.settle_s >= 0 && in.extent_deg > 0 &&
        in.candidate_step_deg > 0 && in.candidate_step_deg <= in.extent_deg && in.count_noise_counts >= 0 &&
        in.ref_noise_arcsec >= 0 && in.target_sigma_arcsec > 0 && !in.samples_choices.empty())) {
    throw std::invalid_argument(
        "design: rate, acceleration, frame rate, extent, candidate step and target must be > 0; settle and noise >= 0; "
        "at least one frames-per-dwell choice");
  }
}

// The transfer functions a design must hold for: the prior first, then also_for.
std::vector<const CoefficientSet*> transfer_functions(const DesignInputs& in) {
  std::vector<const CoefficientSet*> out{&in.prior};
  for (const auto& s : in.also_for) out.push_back(&s);
  return out;
}

// One axis of a design being built, under every transfer function it must hold for: each one's
// cache and information so far; its sigma is the largest over them.
struct RobustAxis {
  std::vector<AxisModelCache> models;
  std::vector<Mat8> info;

  RobustAxis(const DesignInputs& in, bool pitch, const std::vector<double>& cand, int m) {
    for (const CoefficientSet* set : transfer_functions(in)) {
      models.push_back(cache_axis(in, pitch ? set->alpha : set->beta, cand, m));
      info.push_back(models.back().null_info);  // the first null
    }
  }
  // Adds a dwell pair: an offset at candidate k along this axis (else a dwell of the other's), and a null.
  void add(bool along, size_t k) {
    for (size_t i = 0; i < models.size(); ++i) {
      info[i] += (along ? models[i].offset_info[k] : models[i].null_info) + models[i].null_info;
    }
  }
  // The largest sigma over the transfer functions, with candidate k added when given; `which`: whose.
  double sigma(std::optional<size_t> k = std::nullopt, size_t* which = nullptr) const {
    double worst = -1;
    for (size_t i = 0; i < models.size(); ++i) {
      const double s = max_sigma(models[i], k ? Mat8(info[i] + models[i].offset_info[*k] + models[i].null_info) : info[i]);
      if (s > worst) {
        worst = s;
        if (which) *which = i;
      }
    }
    return worst;
  }
};

// Outward: +s, -s, +2s, -2s, ... per axis, pitch first.
std::vector<DesignOffset> ordered(std::vector<DesignOffset> o) {
  std::stable_sort(o.begin(), o.end(), [](const DesignOffset& a, const DesignOffset& b) {
    if (a.pitch != b.pitch) return a.pitch;
    if (std::abs(a.angle_deg) != std::abs(b.angle_deg)) return std::abs(a.angle_deg) < std::abs(b.angle_deg);
    return a.angle_deg > b.angle_deg;
  });
  return o;
}

}  // namespace

double design_time_s(const DesignInputs& in, const std::vector<DesignOffset>& offsets, int m) {
  const double dwell = in.settle_s + m / in.frame_rate_hz;
  double t = dwell;  // the first null
  for (const auto& o : offsets) t += 2 * slew_s(in, o.angle_deg) + 2 * dwell;  // out, offset, back, null
  return t;
}

double predicted_max_sigma_arcsec(const DesignInputs& in, const std::vector<DesignOffset>& offsets, int m, bool pitch) {
  std::vector<double> angles;
  for (const auto& o : offsets) angles.push_back(o.pitch == pitch ? o.angle_deg : 0.0);
  double worst = 0;
  for (const CoefficientSet* set : transfer_functions(in)) {
    const AxisModelCache a = cache_axis(in, pitch ? set->alpha : set->beta, angles, m);
    Mat8 info = a.null_info;  // the first null
    for (size_t k = 0; k < offsets.size(); ++k) info += a.offset_info[k] + a.null_info;
    worst = std::max(worst, max_sigma(a, info));
  }
  return worst;
}

namespace {

std::vector<double> candidates(const DesignInputs& in) {
  std::vector<double> cand;
  const int steps = static_cast<int>(std::floor(in.extent_deg / in.candidate_step_deg + 1e-9));
  for (int i = -steps; i <= steps; ++i) {
    if (i != 0) cand.push_back(i * in.candidate_step_deg);
  }
  return cand;
}

// The greedy design at m frames per dwell: its offsets, time, and sigma per axis (and whose).
struct Greedy {
  std::vector<DesignOffset> offs;
  double time = 0, sp = 0, sy = 0;
  size_t wp = 0, wy = 0;
};

Greedy greedy_design(const DesignInputs& in, const std::vector<double>& cand, int m) {
  RobustAxis ap(in, true, cand, m), ay(in, false, cand, m);
  const double dwell = in.settle_s + m / in.frame_rate_hz;
  Greedy g;
  g.time = dwell;
  auto add = [&](bool pitch, size_t k) {
    g.offs.push_back({pitch, cand[k]});
    ap.add(pitch, k);
    ay.add(!pitch, k);
    g.time += 2 * slew_s(in, cand[k]) + 2 * dwell;
  };
  // Start: 8 offsets per axis at +-extent x {1/4, 1/2, 3/4, 1} (nearest candidates): 9 distinct
  // counts per axis, enough for C2..C8 and the level.
  for (bool pitch : {true, false}) {
    for (double f : {0.25, 0.5, 0.75, 1.0}) {
      for (double sgn : {1.0, -1.0}) {
        const double want = sgn * f * in.extent_deg;
        size_t k = 0;
        for (size_t j = 1; j < cand.size(); ++j)
          if (std::abs(cand[j] - want) < std::abs(cand[k] - want)) k = j;
        add(pitch, k);
      }
    }
  }
  g.sp = ap.sigma(std::nullopt, &g.wp);
  g.sy = ay.sigma(std::nullopt, &g.wy);
  int per_axis[2] = {8, 8};
  while (std::max(g.sp, g.sy) > in.target_sigma_arcsec) {
    // The worse axis gets the offset that lowers its largest sigma most per second.
    const bool pitch = g.sp >= g.sy;
    if (per_axis[pitch ? 0 : 1] >= in.max_offsets_per_axis) break;
    const RobustAxis& a = pitch ? ap : ay;
    const double now = pitch ? g.sp : g.sy;
    double best_gain = -1;
    size_t best_k = 0;
    for (size_t k = 0; k < cand.size(); ++k) {
      const double gain = (now - a.sigma(k)) / (2 * slew_s(in, cand[k]) + 2 * dwell);
      if (gain > best_gain) {
        best_gain = gain;
        best_k = k;
      }
    }
    add(pitch, best_k);
    ++per_axis[pitch ? 0 : 1];
    g.sp = ap.sigma(std::nullopt, &g.wp);
    g.sy = ay.sigma(std::nullopt, &g.wy);
  }
  return g;
}

std::string whose(const DesignInputs& in, size_t i) {
  if (i == 0) return "prior";
  const CoefficientSet& s = in.also_for[i - 1];
  return s.unit.empty() ? fmt::format("transfer function {}", i) : s.unit;
}

}  // namespace

ExperimentDesign design_experiment(const DesignInputs& in) {
  check(in);
  const std::vector<double> cand = candidates(in);
  ExperimentDesign best;
  double best_sigma = std::numeric_limits<double>::infinity();
  for (int m : in.samples_choices) {
    if (m < 1) continue;
    const Greedy g = greedy_design(in, cand, m);
    const bool reached = std::max(g.sp, g.sy) <= in.target_sigma_arcsec;
    const bool better = reached ? (!best.reached || g.time < best.bench_time_s)
                                : (!best.reached && std::max(g.sp, g.sy) < best_sigma);
    if (better) {
      best.reached = reached;
      best.offsets = ordered(g.offs);
      best.samples_per_dwell = m;
      best.bench_time_s = g.time;
      best.max_sigma_arcsec_pitch = g.sp;
      best.max_sigma_arcsec_yaw = g.sy;
      best.limited_by_pitch = whose(in, g.wp);
      best.limited_by_yaw = whose(in, g.wy);
      best_sigma = std::max(g.sp, g.sy);
    }
  }
  if (!best.reached) {
    best.note = fmt::format(
        "target {:.4f} arcsec not reached with up to {} offsets per axis and at most {} frames per dwell: the best "
        "design found gives {:.4f} arcsec",
        in.target_sigma_arcsec, in.max_offsets_per_axis,
        *std::max_element(in.samples_choices.begin(), in.samples_choices.end()), best_sigma);
  }
  return best;
}

}  // namespace fpss
