// Acceptance of a sensor unit: the limits file, the criteria judged on a run's recording, and the certificate.
#pragma once
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/axis_mapping.h"
#include "calib/coefficients.h"
#include "calib/reduction.h"
#include "calib/reference_calibration.h"
#include "calib/samples.h"
#include "calib/uncertainty.h"
#include "procedures/plan.h"
#include "procedures/procedure.h"

namespace fpss {

// ---- limits (procedures/acceptance_limits.yaml) ----

// One limit: its value and where the number comes from (a limit without a source is refused).
struct Limit {
  double value = 0;
  std::string source;
};

struct AcceptanceLimits {
  std::string name, description, origin, sha256;  // origin: the file; sha256 of its text
  Limit residual_mean_abs_arcsec;     // calibration residuals, Table 1 form: mean |r| per axis
  Limit residual_max_abs_arcsec;      // and max |r| per axis
  Limit accuracy_3sigma_arcsec;       // 3 x RMS error at the verification points, per axis
  Limit accuracy_worst_point_arcsec;  // largest error at any verification point, per axis
  Limit accuracy_centre_arcsec;       // largest error at the verification null dwells (the centre)
  Limit accuracy_radius_arcmin;       // accuracy is judged on points this close to the centre
  Limit jitter_3sigma_arcsec;         // 3 x SD at rest (linear trend removed), per axis, worst dwell
  Limit calibrated_range_deg;         // the calibration reaches at least +-this on each axis
  Limit verified_extent_deg;          // the verification reaches at least +-this on each axis
  Limit verification_points_min;      // verification offset points inside the radius
  Limit sun_present_fraction;         // planned points measured with every frame valid (sun present)
  Limit consistency_arcsec;           // max |B - A| against the unit's last accepted or imported calibration, if any
  Limit outlier_frames_fraction;      // share of dwell frames the reduction may reject, per axis (stand policy)
  DecisionRule decision_rule;         // decision_rule: how U enters the verdict (default simple)
};

// Parses a limits file; every error (missing limit, missing source, wrong type, unknown key) at
// once with file:line:column, as InputError.
AcceptanceLimits parse_acceptance_limits(const std::string& text, const std::string& origin);
AcceptanceLimits load_acceptance_limits(const std::filesystem::path& path);
// procedures/acceptance_limits.yaml and procedures/acceptance.yaml of the source tree
// ($FPSS_PROCEDURES_DIR overrides the folder, for an installed copy).
std::filesystem::path default_limits_path();
std::filesystem::path default_acceptance_procedure_path();

// ---- what each point of an acceptance procedure is for ----

enum class PointRole { calibration, verification, rest };
// Its names in acceptance.json and the certificate.
NLOHMANN_JSON_SERIALIZE_ENUM(PointRole, {{PointRole::calibration, "calibration"},
                                         {PointRole::verification, "verification"},
                                         {PointRole::rest, "rest"}})

// Roles by the samples file's step column (point + 1): null_offset_grid before the calibrate
// step -> calibration, null_offset_grid after it -> verification, sample after it -> rest.
// Throws InputError naming the procedure file when it lacks one of the three or has other
// point-making steps (slews, samples before the calibrate step, a second calibrate).
std::map<int64_t, PointRole> acceptance_roles(const Procedure& proc, const Plan& plan);

// ---- judging ----

struct AcceptanceData {
  SampleTable samples;                       // the run's recording (valid frames only)
  std::map<int64_t, PointRole> roles;        // by step
  size_t points_planned = 0;
  std::optional<CoefficientSet> calibration; // the run's fit (calibration.json), absent if it never ran
  std::optional<CoefficientSet> previous;    // the unit's last accepted or imported calibration
  std::string previous_name;                 // how to name it in the certificate
  bool run_completed = true;
  std::string run_reason;                    // why the run stopped early
  // The reference's own calibration (the stand file's `reference:`), which the engine applied to the
  // readings: its u is in the accuracy criteria's budgets (the calibration inherits the reference's
  // error, and a verification against the same reference cannot see it). None: no such entries.
  std::optional<ReferenceCalibration> reference;
  AxisMapping mount;                         // how the unit sits on the gimbal (the reference's terms)
};

struct Criterion {
  std::string id;        // e.g. jitter_3sigma_pitch
  std::string title;
  std::string axis;      // pitch (alpha), yaw (beta) or "" for both
  std::optional<double> measured;  // absent: could not be measured (fails)
  double uncertainty = 0;          // 1 sigma of the measured value, same unit: budget's combined u
  std::vector<BudgetEntry> budget; // its contributions (empty when the value is exact: counts, encoder ranges)
  Combined combined;               // u, dof_eff, k, U of the budget
  double limit = 0;
  std::string relation;  // "<=" or ">="
  std::string unit;      // arcsec, deg, points, fraction
  Decision decision;             // under the limits file's rule
  Outcome simple_outcome = Outcome::fail;  // what the simple rule would say (the certificate says why they differ)
  bool passed = false;           // decision.outcome == pass
  std::string limit_key; // the limits file's key
  std::string source;    // where the limit comes from
  std::string detail;    // how it was measured, where the worst value is
};

// One verification or rest dwell as the judge saw it (for the certificate and the report).
struct JudgedPoint {
  int64_t step = 0;
  PointRole role = PointRole::verification;
  Phase phase = Phase::offset;
  double ref_pitch_arcsec = 0, ref_yaw_arcsec = 0;
  size_t frames = 0;                              // frames the reduction kept
  size_t outliers_pitch = 0, outliers_yaw = 0;    // frames it left out, by the axis that was off
  double error_pitch_arcsec = 0, error_yaw_arcsec = 0;  // calibrated angle - reference (mean over frames)
  double se_pitch_arcsec = 0, se_yaw_arcsec = 0;        // standard error of those means
  double jitter3_pitch_arcsec = 0, jitter3_yaw_arcsec = 0;  // rest dwells: 3 x SD, trend removed
};

struct Judgement {
  OutlierSummary outliers;  // the reduction's rejected frames over the whole recording
  std::vector<Criterion> criteria;
  std::vector<JudgedPoint> points;  // verification and rest dwells
  DecisionRule rule;
  Outcome outcome = Outcome::fail;  // fail if any criterion fails, else conditional if any is, else pass
  bool passed = false;              // outcome == pass
  std::vector<std::string> failed() const;       // ids of the failed criteria
  std::vector<std::string> conditional() const;  // ids of the conditional ones
};

// Pure: the criteria from the data and the limits (no files, no clock).
Judgement judge(const AcceptanceData& data, const AcceptanceLimits& limits);

// ---- the certificate ----

// Who and what was judged, for the certificate.
struct CertificateInfo {
  std::string unit;
  std::string stand;                    // stand identity (stand id or file; "emulated bench (...)")
  nlohmann::json stand_detail = nlohmann::json::object();
  std::string software_version = FPSS_VERSION;
  std::string procedure_name, procedure_file, procedure_sha256;
  std::string run_id, run_dir, run_outcome, run_reason;
  int64_t points_planned = 0, points_completed = 0;
  std::string date_utc;
  std::string calibration_file;         // "" when there is none
  nlohmann::json reference;             // the reference calibration file's identity(); null: none
  // The calibrated angle's GUM figures, per axis, as calibration.json has them (calibration_uncertainty()).
  nlohmann::json calibration_uncertainty;
};

// Of calibration.json's `uncertainties`: per axis {expanded_uncertainty_max_arcsec, coverage_factor,
// dof_eff, budget_angle_arcsec, budget}; null when it has none (an older file, or no listed angles).
nlohmann::json calibration_uncertainty(const nlohmann::json& uncertainties);

// acceptance.json: {"format": "fpss-stand acceptance/1", "verdict": "pass"|"conditional"|"fail",
// "passed", "unit", "stand", "software", "procedure", "limits", "decision_rule", "run", "date_utc",
// "calibration", "criteria": [{id, title, axis, measured, uncertainty, expanded_uncertainty,
// coverage_factor, dof_eff, budget, limit, acceptance_limit, relation, unit, outcome, passed,
// limit_key, source, detail}], "failed": [...], "conditional": [...], "points": [...]} (docs/acceptance.md).
nlohmann::ordered_json certificate_json(const Judgement& j, const AcceptanceLimits& limits, const CertificateInfo& info);
// The certificate as plain text (certificate.txt) and as a report.html section (trusted markup).
std::string certificate_text(const nlohmann::ordered_json& cert);
std::string certificate_html(const nlohmann::ordered_json& cert);

}  // namespace fpss
