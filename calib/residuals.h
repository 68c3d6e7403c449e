// What the fit sees of one axis, the scaled parameters Ceres moves, and the residual functors
// (templated over the one transfer function, so they serve doubles and Ceres jets alike).
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <vector>

#include "calib/quantisation.h"
#include "calib/transfer_function.h"
#include "calib/units.h"

namespace fpss::fit {

// Counts over half the field: the unit the count axis is scaled by inside the fit.
inline constexpr double kCountScale = 16384.0;
// The prelaunch scale factor (Table A-1, Table 2 footnote a), rad/count.
inline constexpr double kNominalC2 = 0.5326322e-6;

// One axis's data as the fit sees it.
//  differences: one row per change, ref_change = f(n_plus) - f(n_minus), n_plus at the offset dwell,
//               n_minus at its null dwell; C1 cancels and follows from the null condition.
//  absolute:    one row per dwell, ref = f(n_plus); n_minus is unused (0).
// Rows are either given explicitly (the vectors n_plus, n_minus, y_arcsec) or, for the differences
// method fed dwell by dwell (add_pair_rows), held as the pair of dwells they join: a change costs
// 8 bytes, its numbers are the dwells'. Read rows through the accessors, which see both.
struct AxisData {
  bool differences = true;
  std::vector<double> n_plus, n_minus, y_arcsec;  // explicit rows (come first)
  // The null condition (paper eq. 3): the mean null-dwell counts and reference.
  double null_counts_sum = 0, null_ref_arcsec_sum = 0;
  size_t null_dwells = 0;
  // What the rows cover: counts and reference angle of the dwells used.
  double counts_lo = 0, counts_hi = 0, ref_lo_arcsec = 0, ref_hi_arcsec = 0;
  bool covered = false;

  // The dwells themselves (differences method), for the fit with the changes' covariance: one
  // entry per dwell, in order (24 bytes: memory grows with the dwells, so they are kept small);
  // `link` is the union-find parent (dwells joined by a change share one reference level).
  struct DwellRow {
    double counts = 0, ref_arcsec = 0;
    uint32_t link = 0;
    // samples (low 20 bits, at most 1,048,575), the reference's independent readings as a share
    // of them (10 bits, of 1023: 1023 when each frame has its own), kWholeBit, kNullBit.
    uint32_t info = 0;
    static constexpr uint32_t kNullBit = 1u << 31, kWholeBit = 1u << 30, kSamplesMask = (1u << 20) - 1;
    static constexpr int kShareShift = 20;
    static constexpr uint32_t kShareMax = 1023;
    uint32_t samples() const { return info & kSamplesMask; }
    bool null() const { return (info & kNullBit) != 0; }
    bool whole_counts() const { return (info & kWholeBit) != 0; }
    // What the reference mean is worth in independent readings (samples() when each frame has its own).
    double ref_readings() const {
      const uint32_t share = (info >> kShareShift) & kShareMax;
      return share == kShareMax ? static_cast<double>(samples()) : samples() * (share / static_cast<double>(kShareMax));
    }
    static uint32_t pack(size_t samples, double ref_readings_eff, bool null, bool whole) {
      const size_t n = std::min<size_t>(samples, kSamplesMask);
      const double share = samples > 0 ? std::clamp(ref_readings_eff / static_cast<double>(samples), 0.0, 1.0) : 1.0;
      const auto q = static_cast<uint32_t>(std::max(1.0, std::round(share * kShareMax)));
      return static_cast<uint32_t>(n) | (q << kShareShift) | (null ? kNullBit : 0u) | (whole ? kWholeBit : 0u);
    }
  };
  // Chunked (no reallocation peak of twice the size while growing).
  std::deque<DwellRow> dwells;
  // Each dwell's sensor temperature, C (NaN: none), beside `dwells` (the budget's temperature entry).
  std::deque<float> dwell_temperature_c;
  struct Change {
    uint32_t null_dwell = 0, offset_dwell = 0;  // into `dwells`
  };
  std::deque<Change> changes;  // rows after the explicit ones
  // The dwells' within-dwell scatter, pooled as they are added (what the noise model needs of it):
  // sums over dwells of two or more frames of (frames - 1) x variance, and the count scatter by
  // the fractional part of the count (the count noise's estimate, calib/quantisation.h).
  double ref_scatter_ss = 0, count_scatter_ss = 0, scatter_dof = 0, ref_scatter_dof = 0;
  bool all_whole_counts = true;
  CountNoiseEstimator count_scatter;
  // Steps of the latest dwells (pairs and nulls arrive in recording order): finds a dwell again.
  static constexpr size_t kRecentSteps = 64;
  std::array<int64_t, kRecentSteps> recent_steps{};

  size_t rows() const { return y_arcsec.size() + changes.size(); }
  double row_n_plus(size_t i) const {
    return i < y_arcsec.size() ? n_plus[i] : dwells[changes[i - y_arcsec.size()].offset_dwell].counts;
  }
  double row_n_minus(size_t i) const {
    if (i < y_arcsec.size()) return differences ? n_minus[i] : 0.0;
    return dwells[changes[i - y_arcsec.size()].null_dwell].counts;
  }
  double row_y_arcsec(size_t i) const {
    if (i < y_arcsec.size()) return y_arcsec[i];
    const Change& c = changes[i - y_arcsec.size()];
    return dwells[c.offset_dwell].ref_arcsec - dwells[c.null_dwell].ref_arcsec;
  }
  size_t parameters() const { return differences ? 7 : 8; }
  double null_counts() const { return null_counts_sum / static_cast<double>(null_dwells); }
  double null_ref_arcsec() const { return null_ref_arcsec_sum / static_cast<double>(null_dwells); }
  void cover(double counts, double ref_arcsec) {
    if (!covered) {
      counts_lo = counts_hi = counts;
      ref_lo_arcsec = ref_hi_arcsec = ref_arcsec;
      covered = true;
      return;
    }
    counts_lo = std::min(counts_lo, counts); counts_hi = std::max(counts_hi, counts);
    ref_lo_arcsec = std::min(ref_lo_arcsec, ref_arcsec); ref_hi_arcsec = std::max(ref_hi_arcsec, ref_arcsec);
  }
};

// Whether row i belongs to an evenly spread subset holding `fraction` of the rows. Golden-ratio
// (Weyl) selection rather than every k-th row: recordings are periodic (pitch and yaw offsets
// alternate, each offset gives a change forward and one back), and a stride of 4 would keep
// only the forward changes of pitch offsets and leave yaw with nothing to fit.
inline bool in_spread_subset(size_t i, double fraction) {
  if (fraction >= 1.0) return true;
  constexpr double kGolden = 0.6180339887498949;
  const double x = static_cast<double>(i) * kGolden;
  return x - static_cast<double>(static_cast<uint64_t>(x)) < fraction;
}

// Scaled coefficients u, chosen so every Jacobian column is of order 1..100 arcsec
// (raw C2 columns are ~1e9 times larger than C5 columns). S = kCountScale, k = arcsec per rad:
//   u[0] = C1 k   [arcsec]            (absolute method only; differences fit u[1..7])
//   u[1] = C2 k S [arcsec over S counts]
//   u[2] = C3 k   [arcsec]   u[3] = C4 S [rad over S counts]   u[4] = C5 [rad]
//   u[5] = C6 k   [arcsec]   u[6] = C7 S                       u[7] = C8 [rad]
using Scaled = std::array<double, 8>;

// C_i = u_i * factor_i.
inline constexpr std::array<double, 8> kScaleFactor = {
    1 / kArcsecPerRad, 1 / (kArcsecPerRad * kCountScale), 1 / kArcsecPerRad, 1 / kCountScale, 1.0,
    1 / kArcsecPerRad, 1 / kCountScale, 1.0};

inline Scaled to_scaled(const AxisCoeffs& c) {
  Scaled u{};
  for (size_t i = 0; i < 8; ++i) u[i] = c[i] / kScaleFactor[i];
  return u;
}
inline AxisCoeffs from_scaled(const Scaled& u) {
  AxisCoeffs c{};
  for (size_t i = 0; i < 8; ++i) c[i] = u[i] * kScaleFactor[i];
  return c;
}

// Coefficients of the same transfer function giving arcsec instead of radians, from u[1..7]
// (`u27`) and C1 in arcsec: transfer_angle(c.data(), N) is then the angle in arcsec.
template <typename T>
inline std::array<T, 8> arcsec_coeffs(const T* u27, const T& c1_arcsec) {
  return {c1_arcsec, u27[0] / kCountScale, u27[1], u27[2] / kCountScale, u27[3], u27[4], u27[5] / kCountScale, u27[6]};
}

// Residuals of a run of difference rows, arcsec. Parameter block: u[1..7] (7 values).
struct DifferenceResiduals {
  const double* n_plus;
  const double* n_minus;
  const double* ref_change_arcsec;
  int count;

  template <typename T>
  bool operator()(const T* u27, T* r) const {
    const std::array<T, 8> c = arcsec_coeffs(u27, T(0.0));
    for (int i = 0; i < count; ++i) {
      r[i] = transfer_angle(c.data(), n_plus[i]) - transfer_angle(c.data(), n_minus[i]) - ref_change_arcsec[i];
    }
    return true;
  }
};

// Residuals of a run of absolute rows, arcsec. Parameter block: u[0..7] (8 values).
struct AbsoluteResiduals {
  const double* n;
  const double* ref_arcsec;
  int count;

  template <typename T>
  bool operator()(const T* u, T* r) const {
    const std::array<T, 8> c = arcsec_coeffs(u + 1, u[0]);
    for (int i = 0; i < count; ++i) r[i] = transfer_angle(c.data(), n[i]) - ref_arcsec[i];
    return true;
  }
};

// One dwell against its reference level (the GLS form of the differences method): the fitted angle at
// the dwell's counts, C1 replaced by the level the changes tie it to, minus its reference, in
// standard deviations. u27 are u[1..7], level in arcsec.
struct DwellLevelResidual {
  double counts, ref_arcsec, inv_sigma;

  template <typename T>
  T operator()(const T* u27, const T& level_arcsec) const {
    const std::array<T, 8> c = arcsec_coeffs(u27, level_arcsec);
    return (transfer_angle(c.data(), T(counts)) - T(ref_arcsec)) * inv_sigma;
  }
};

// Residual of row i in arcsec for plain coefficients (radians), for statistics.
inline double residual_arcsec(const AxisData& d, const AxisCoeffs& c, size_t i) {
  if (d.differences) {
    return rad_to_arcsec(transfer_angle(c.data(), d.row_n_plus(i)) - transfer_angle(c.data(), d.row_n_minus(i))) -
           d.row_y_arcsec(i);
  }
  return rad_to_arcsec(transfer_angle(c.data(), d.row_n_plus(i))) - d.row_y_arcsec(i);
}

}  // namespace fpss::fit
