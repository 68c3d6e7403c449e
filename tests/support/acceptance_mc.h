// Coverage of the accuracy criteria's expanded uncertainty U on recordings of the independent
// generator (tests/gen/grid_gen.py --verification): each recording is calibrated on its grid and
// judged; each accuracy criterion's measured value is compared with its true value, the same figure
// from the unit's true errors (the calibrated transfer function against the generator's truth at the
// true angles: no sensor noise, no reference error). Shared by the acceptance benchmark and its
// small ctest.
#pragma once
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "calib/calibrator.h"
#include "calib/reference_fit.h"
#include "stand/acceptance/acceptance.h"
#include "tests/support/calib_mc.h"

namespace fpss::test::mc {

// How often |measured - true| <= U.
struct Tally {
  size_t covered = 0, cases = 0;
  double sum_ratio = 0;  // |measured - true| / U, for the mean
  void add(double measured, double truth, double big_u) {
    covered += std::abs(measured - truth) <= big_u;
    ++cases;
    sum_ratio += big_u > 0 ? std::abs(measured - truth) / big_u : 0.0;
  }
  double rate() const { return cases ? static_cast<double>(covered) / static_cast<double>(cases) : 0.0; }
};

inline const Criterion& criterion_of(const Judgement& j, const std::string& id) {
  for (const auto& c : j.criteria) {
    if (c.id == id) return c;
  }
  throw std::runtime_error("no criterion " + id);
}

// Per criterion ("worst_point pitch", "centre yaw", "3sigma pitch", ...): how often U covered the
// true value. `reference`: the reference file the generator drew the gimbal's errors from, which
// corrects the readings and enters the budgets (the engine's and the stand file's part).
inline std::map<std::string, Tally> accuracy_coverage(const std::vector<fs::path>& files, const Design& design,
                                                      const CoefficientSet& truth,
                                                      const std::optional<ReferenceCalibration>& reference,
                                                      const AcceptanceLimits& limits) {
  const double radius_arcsec = limits.accuracy_radius_arcmin.value * 60.0;
  const auto steps = design.step_angles_arcsec();
  const auto grid = static_cast<int64_t>(design.grid_steps());
  CalibrationOptions correct;
  correct.reference = reference;
  correct.correct_reference = reference.has_value();
  CalibrationOptions o = correct;
  o.threads = 1;
  o.correct_reference = false;  // the engine's part: the readings are corrected once, below
  std::map<std::string, Tally> tallies;
  for (const auto& f : files) {
    const SampleTable t = with_reference_applied(read_samples_csv(f), correct);
    AcceptanceData data;
    for (int64_t s = 1; s <= static_cast<int64_t>(steps.size()); ++s) {
      data.roles[s] = s <= grid ? PointRole::calibration : PointRole::verification;
    }
    data.points_planned = steps.size();
    data.calibration = calibrate(t.up_to_step(grid), o).coefficients();
    data.reference = reference;
    data.samples = t;
    const Judgement j = judge(data, limits);
    for (int ax = 0; ax < 2; ++ax) {
      const AxisModel fitted = ax == 0 ? data.calibration->alpha_model() : data.calibration->beta_model();
      const AxisModel true_model(ax == 0 ? truth.alpha : truth.beta);
      // The unit's true error at a step: its calibrated angle of the counts the truth gives there.
      const auto true_error = [&](int64_t step) {
        const double angle = steps.at(static_cast<size_t>(step - 1))[ax];
        return fitted.angle_arcsec(true_model.counts_for_angle(arcsec_to_rad(angle))) - angle;
      };
      const std::string axis = ax == 0 ? "pitch" : "yaw";
      const std::function<bool(const JudgedPoint&)> inside = [&](const JudgedPoint& p) {
        return p.phase == Phase::offset && std::hypot(p.ref_pitch_arcsec, p.ref_yaw_arcsec) <= radius_arcsec + 1e-6;
      };
      const std::function<bool(const JudgedPoint&)> null = [](const JudgedPoint& p) { return p.phase == Phase::null; };
      for (const auto& [kind, keep] : {std::pair{std::string("worst_point"), inside}, std::pair{std::string("centre"), null}}) {
        // The true figure is the worst true error over the same dwells (the measured one picks its
        // dwell by the noisy errors).
        const Criterion& c = criterion_of(j, "accuracy_" + kind + "_" + axis);
        double worst_true = -1;
        for (const auto& p : j.points) {
          if (p.role == PointRole::verification && keep(p)) worst_true = std::max(worst_true, std::abs(true_error(p.step)));
        }
        if (c.measured && worst_true >= 0) tallies[kind + " " + axis].add(*c.measured, worst_true, c.combined.U);
      }
      const Criterion& rms = criterion_of(j, "accuracy_3sigma_" + axis);
      double ss = 0;
      size_t n = 0;
      for (const auto& p : j.points) {
        if (p.role != PointRole::verification || !inside(p)) continue;
        ss += true_error(p.step) * true_error(p.step);
        ++n;
      }
      if (rms.measured && n > 0) tallies["3sigma " + axis].add(*rms.measured, 3.0 * std::sqrt(ss / static_cast<double>(n)), rms.combined.U);
    }
  }
  return tallies;
}

}  // namespace fpss::test::mc
