// A procedure expanded for one stand: a flat list of actions with numbered points, checked against the soft limits.
#pragma once
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "procedures/settings.h"
#include "procedures/procedure.h"

namespace fpss {

// One thing the engine does. Points (dwells and slew segments) carry the identity that makes a
// resumed run measure exactly the points an uninterrupted one would: their index in this plan,
// which depends only on the procedure text and the stand's sample rate.
struct Action {
  enum class Kind { home, move, settle, dwell, slew, calibrate, check, diagnose };
  Kind kind = Kind::move;
  size_t step_index = 0;     // the procedure step it came from (1-based)
  TextMark mark;             // where that step is written
  // Point identity: index 0.. among points; the samples file's `step` column is point + 1.
  int64_t point = -1;
  Phase phase = Phase::move;
  // Targets in the stand frame (dwell: where to measure; slew: the far end, where the first leg goes).
  double pitch_arcsec = 0, yaw_arcsec = 0;
  double rate_arcsec_s = 0;  // move/slew profile speed; 0: stand default
  double settle_s = 0;       // settle: its duration; dwell/slew: wait after arriving, before sampling
  int frames = 0;            // dwell: frames to keep
  int max_invalid = 0;
  double timeout_s = 0;      // home: physical seconds (0: stand default)
  // slew: start point and sampling
  double start_pitch_arcsec = 0, start_yaw_arcsec = 0;
  double sample_period_s = 0;
  int reversals = 0;  // slew: turns inside the segment, legs alternate far end / start (last target: end_*)
  StandAxis axis = StandAxis::pitch;  // slew: the axis; adaptive stop: the group's axis
  // Adaptive stop (a grid's `until`): the points of one group (a grid axis, or the whole grid
  // when its points move both axes) end once the live fit's largest 1-sigma is at most this.
  double until_sigma_arcsec = 0;  // 0: no adaptive stop
  int until_group = -1;           // unique in the plan
  bool until_both_axes = false;   // the group moves both axes (else only `axis`)
  const CalibrateStep* calibrate = nullptr;  // into the Procedure, which must outlive the plan
  const CheckStep* check = nullptr;
  const DiagnoseStep* diagnose = nullptr;

  // slew: where the segment ends (the far end, or the start after an odd number of reversals).
  double end_pitch_arcsec() const { return reversals % 2 ? start_pitch_arcsec : pitch_arcsec; }
  double end_yaw_arcsec() const { return reversals % 2 ? start_yaw_arcsec : yaw_arcsec; }
  // slew: where leg k goes (legs alternate far end / start; a.reversals turns inside the segment).
  std::pair<double, double> leg_target(int k) const {
    return k % 2 == 0 ? std::pair{pitch_arcsec, yaw_arcsec} : std::pair{start_pitch_arcsec, start_yaw_arcsec};
  }
  double slew_span_arcsec() const {
    return axis == StandAxis::pitch ? std::abs(pitch_arcsec - start_pitch_arcsec) : std::abs(yaw_arcsec - start_yaw_arcsec);
  }
  bool is_point() const { return kind == Kind::dwell || kind == Kind::slew; }
  std::string describe() const;  // one line for --dry-run and the log
};

struct Plan {
  std::vector<Action> actions;
  size_t points = 0;
  size_t frames = 0;             // frames kept at dwells (slews: estimated samples)
  // The physical minimum (bench seconds): the moves at the gimbal's profile rate and acceleration,
  // the settles and the dwells' frames.
  double physical_s = 0;
  // What a run should take (bench seconds): the physical minimum plus what the device links cost
  // at the stand's speed-up (EngineSettings::link_round_trip_s); the --dry-run figure.
  double estimated_s = 0;
  // Index in `actions` of each point.
  std::vector<size_t> point_action;
};

// Expands the procedure for the stand; errors (a target outside the soft limits, a rate above
// the limit, a sample period shorter than the sensor's) go to `d` with the step's file:line:col.
// Steps that failed to parse are skipped, so a procedure with errors can still be checked.
Plan expand(const Procedure& proc, const EngineSettings& bench, Diagnostics& d);

// Physical seconds for a point-to-point move with a trapezoidal profile on both axes at once.
double move_duration_s(double from_pitch, double from_yaw, double to_pitch, double to_yaw, double rate_arcsec_s,
                       double accel_arcsec_s2);

// The --dry-run text: every action, the number of points, the estimated duration.
std::string format_plan(const Procedure& proc, const Plan& plan, const EngineSettings& bench);

}  // namespace fpss
