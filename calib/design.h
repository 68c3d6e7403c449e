// Optimal experiment design for a null-to-offset calibration: which offsets, how many frames per
// dwell, in which order, so that the calibrated transfer function reaches a target 1-sigma over the
// range in the least bench time. The core of `fpss-stand design --target-sigma-arcsec S`.
//
// Interface (for the command and the procedure writer):
//   DesignInputs in;                       // bench: gimbal rate/acceleration, settle, frame rate;
//   in.prior = load_coefficients(...);     // noise; range; the target; a prior transfer function
//   in.target_sigma_arcsec = 0.02;
//   const ExperimentDesign d = design_experiment(in);
//   d.reached                  -> the target is met (else d.note says why not, and d is the best found)
//   d.offsets                  -> in recording order: each one is null -> offset -> null, nulls shared
//                                 (null, o1, null, o2, null, ...: the paper's procedure)
//   d.samples_per_dwell, d.bench_time_s, d.max_sigma_arcsec_{pitch,yaw}
//
// The model: the fit of calibrator.h (GLS of the changes: each dwell with its reference and count
// variance, one reference level, C1 by the null condition), its covariance predicted from the
// Fisher information at the prior. Time per dwell: settle + frames / frame rate; per offset: the
// slew out and back (trapezoidal profile at the rate and acceleration). Search: for each candidate
// frames-per-dwell, start from a few offsets per axis spread over the range and add greedily the
// candidate offset (every `candidate_step_deg`) that lowers the largest predicted sigma over the
// range most per second of bench time (G-optimal), until the target is met; the cheapest design
// over the frames-per-dwell candidates wins. Order: outward (+s, -s, +2s, ...) along pitch, then yaw.
//
// Robust design: a design G-optimal for one transfer function can leave another's sigma well above
// the target (the a-6-fpss1 design's pitch sigma under a-1-fpss2 is 1.5x it), so `also_for` lists
// other transfer functions the unit may have (the published sets); the design then meets the target
// under each of them, the greedy step lowering the largest sigma over all (minimax G-optimal).
#pragma once
#include <string>
#include <vector>

#include "calib/coefficients.h"

namespace fpss {

struct DesignInputs {
  CoefficientSet prior;  // a transfer function near the unit's (published or last calibration)
  std::vector<CoefficientSet> also_for;  // the target must hold under these too (robust design)
  double target_sigma_arcsec = 0.02;  // largest 1-sigma of the fitted angle over the range, both axes
  double extent_deg = 0.42;           // offsets within +-extent along pitch and along yaw (the paper's grid)
  double candidate_step_deg = 0.01;   // candidate offsets every this much
  double rate_deg_s = 0.5;            // gimbal slew rate
  double accel_deg_s2 = 1.0;          // gimbal acceleration
  double settle_s = 0.5;              // after each move, before sampling
  double frame_rate_hz = 10.0;        // sensor frames per second
  double count_noise_counts = 0.3;    // per frame, before whole-count rounding
  double ref_noise_arcsec = 0.05;     // per frame
  std::vector<int> samples_choices = {5, 10, 20, 50, 100, 200, 500};
  int max_offsets_per_axis = 200;
};

struct DesignOffset {
  bool pitch = true;  // along pitch (else yaw)
  double angle_deg = 0;
};

struct ExperimentDesign {
  bool reached = false;
  std::string note;
  std::vector<DesignOffset> offsets;  // recording order, each between two nulls
  int samples_per_dwell = 0;
  double bench_time_s = 0;
  double max_sigma_arcsec_pitch = 0, max_sigma_arcsec_yaw = 0;  // the largest over the prior and also_for
  std::string limited_by_pitch, limited_by_yaw;  // whose sigma that is: "prior" or an also_for set's unit
};

// Throws std::invalid_argument for inputs that cannot describe a bench (non-positive rate, ...).
ExperimentDesign design_experiment(const DesignInputs& in);

// The predicted largest 1-sigma (arcsec) over +-extent_deg of one axis for a given design, under
// the prior and each of also_for (the largest).
double predicted_max_sigma_arcsec(const DesignInputs& in, const std::vector<DesignOffset>& offsets,
                                  int samples_per_dwell, bool pitch);
// Bench time of a design (slews, settles, frames).
double design_time_s(const DesignInputs& in, const std::vector<DesignOffset>& offsets, int samples_per_dwell);

}  // namespace fpss
