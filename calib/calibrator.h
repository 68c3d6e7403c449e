// The calibrator: fits both axes' transfer functions to a null-to-offset recording (paper section 2).
#pragma once
#include <array>
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "calib/dwells.h"
#include "calib/reduction.h"
#include "calib/reference_calibration.h"
#include "calib/refine.h"
#include "calib/residuals.h"
#include "calib/samples.h"
#include "calib/uncertainty.h"
#include "calib/varpro.h"

namespace fpss {

enum class Method {
  differences,  // the paper's: C2..C8 on changes null <-> offset, C1 from the null condition
  absolute,     // C1..C8 on the dwells' absolute reference angles
};
std::string_view to_string(Method m);
std::optional<Method> parse_method(std::string_view s);

// How an axis was fitted: gls (the changes with their covariance: dwells, one level per joined
// set, weighted by the noise model) or ols (changes or absolute angles, equal weights).
enum class FitForm { ols, gls };
// Its names in calibration.json (uncertainties.<axis>.fit).
NLOHMANN_JSON_SERIALIZE_ENUM(FitForm, {{FitForm::ols, "ols"}, {FitForm::gls, "gls"}})

struct CalibrationOptions {
  Method method = Method::differences;
  std::optional<CoefficientSet> init;  // also tried as a start, besides the grid's best nodes
  fit::GridConfig grid;
  // Per axis, the grid stage uses at most about this many rows (an evenly spread subset beyond,
  // fit::in_spread_subset); the refinement always uses all of them.
  size_t grid_max_rows = 30000;
  // Competing starts are refined on at most this many rows; only the winner sees all rows.
  size_t screen_max_rows = 20000;
  size_t refine_nodes = 4;  // grid local minima refined
  int threads = 0;  // Ceres threads; 0: the machine's
  int max_iterations = 200;
  std::string unit;  // written to the coefficient set

  // Gaussian count noise per frame before whole-count rounding, counts (the stand file's expected
  // noise). Unset: the start set's (--init) `count_noise_counts` key, else estimated from the
  // within-dwell scatter. Used for the quantisation correction and the dwells' weights.
  std::optional<double> count_noise_counts;
  std::string count_noise_source = "caller";  // how the report names a given noise ("stand file", ...)
  // Frames far from the running median of their step are left out of the dwell means (calib/outliers.h).
  bool reject_outliers = true;
  // The differences method fits the changes with their covariance (GLS); false: the plain
  // least squares of the changes (for comparison).
  bool gls = true;
  // Dwell means of whole counts are replaced by the count whose expected rounded value they are,
  // when the count noise is known or estimated (false: for comparison).
  bool quantisation_correction = true;
  // chi2/dof of the dwell residuals beyond 1 + this many sqrt(2/dof) is a model remainder (4: the
  // weights come from estimated noise, which widens chi2's scatter beyond its textbook one).
  double remainder_sigmas = 4.0;
  // Angles at which the calibration's 1-sigma is listed (evenly over the calibrated range).
  int sigma_angles = 41;
  // The reference range [lo, hi] (arcsec, sensor frame) over which those angles are spread, per
  // axis; unset: the range the data cover. A streaming fit asks over the range a run will cover,
  // so that a sigma from the points so far is not small only because their range is.
  std::optional<std::array<double, 2>> sigma_range_pitch_arcsec, sigma_range_yaw_arcsec;

  // The reference's own calibration (calib/reference_calibration.h): its u is added to the angle
  // sigmas of the final fit (calib/reference_fit.h) and calibration.json names it. With
  // `correct_reference`, every row's reference angles are corrected by it first (a raw recording);
  // without, they already were (a run whose stand file named it). `mount` takes the rows'
  // sensor-frame reference angles to the gimbal's axes the file describes.
  std::optional<ReferenceCalibration> reference;
  bool correct_reference = false;
  AxisMapping mount;

  // The reduction's options these imply (the outlier rule and its noise).
  ReductionOptions reduction() const { return {reject_outliers, count_noise_counts, count_noise_source}; }
};

// Table 1 of the paper: residuals of one axis's fit, arcsec.
struct ResidualStats {
  double mean_abs_arcsec = 0;
  double sd_arcsec = 0;  // standard deviation of |residual| (Table 1 prints mean |r| +- sd)
  double max_abs_arcsec = 0;
  double rms_arcsec = 0;
  size_t points = 0;
  std::array<double, 2> range_deg{};  // reference angles of the dwells used, [lo, hi]
};

struct SolverInfo {
  std::string start;  // which start won: "grid w=(..)" or "init"
  size_t candidates = 0;  // starts refined
  size_t grid_rows = 0;  // rows the grid stage saw
  double grid_rms_arcsec = 0;  // residual RMS at the best grid node
  std::string brief;  // Ceres BriefReport of the final least-squares refinement (with GLS: the start it refines)
  int iterations = 0;
  // 0.5 sum r^2 over the changes, arcsec^2 (final: the Table 1 residuals' sum). Plain least
  // squares: Ceres's, at the winning start and at the end. GLS: under the nominal scale factor
  // alone (where the search starts) and at the returned coefficients.
  double initial_cost = 0, final_cost = 0;
  bool converged = false;
  // The fit with the changes' covariance (differences method, dwells known): Gauss-Newton iterations.
  int gls_iterations = 0;
  bool gls_converged = false;
};

// What the fit knew of the noise, per axis.
struct NoiseInfo {
  double count_noise_counts = std::numeric_limits<double>::quiet_NaN();  // per frame, before rounding
  // "caller" (or what CalibrationOptions::count_noise_source says), "coefficient file",
  // "within-dwell scatter" or "unknown"
  std::string count_noise_source = "unknown";
  double ref_noise_arcsec = std::numeric_limits<double>::quiet_NaN();  // per frame, within-dwell scatter
  bool quantisation_corrected = false;  // dwell counts are E[round(n + e)] inverted, not raw means
};

struct AxisFit {
  std::string axis;  // "pitch" or "yaw"
  std::string coefficient_key;  // "alpha" or "beta"
  AxisCoeffs coeffs{};
  std::array<double, 8> sigma{};  // 1-sigma of C1..C8
  double angle_sigma_max_arcsec = 0;  // 1-sigma of the fitted angle, max over the count range
  bool covariance_pseudo_inverse = false;
  std::string covariance_note;
  std::array<double, 2> counts_range{};  // the calibrated count range
  ResidualStats residuals;
  SolverInfo solver;

  FitForm fit_form = FitForm::ols;
  NoiseInfo noise;
  // [angle_arcsec, sigma_arcsec]: 1-sigma of (fitted - true angle) at evenly spaced angles over the
  // calibrated reference range, C1 (the null condition) included.
  std::vector<std::array<double, 2>> angle_sigma_arcsec;
  // Per listed angle, its uncertainty budget (GUM): the sources whose root sum of squares is that
  // angle's sigma (sensor noise, quantisation, reference noise, model and fit, then each term of
  // the reference's calibration); empty where the angle is not reached.
  std::vector<std::vector<BudgetEntry>> angle_budget;
  // The fit's covariance of the scaled coefficients (residuals.h, C1 first) split by source: each
  // one's angle sigma is its entry in angle_budget, and the Monte Carlo check draws from them.
  struct CovarianceSource {
    std::string source;
    char type = 'A';
    double dof = std::numeric_limits<double>::infinity();
    Eigen::Matrix<double, 8, 8> covariance_scaled = Eigen::Matrix<double, 8, 8>::Zero();
  };
  std::vector<CovarianceSource> covariance_sources;
  double reduced_chi2 = std::numeric_limits<double>::quiet_NaN();  // of the standardised dwell residuals
  size_t chi2_dof = 0;
  bool model_remainder = false;  // reduced chi2 materially > 1: sigmas scaled up by sigma_scale
  double sigma_scale = 1.0;
  size_t dwells_fitted = 0, levels = 0;
  // The reference calibration's u at the worst listed angle (arcsec), already in the angle sigmas;
  // NaN without a reference file.
  double reference_u_max_arcsec = std::numeric_limits<double>::quiet_NaN();
  // The sensor's temperature during the recording and how it moved the fit (GLS only): its entry
  // in every listed angle's budget.
  fit::TemperatureInfluence temperature;

  // The largest listed angle sigma; infinite when none is listed or an angle is not reached (the
  // fit cannot yet speak for the whole range).
  double listed_sigma_max_arcsec() const;
  // The listed angle whose budget has the largest expanded uncertainty U (GUM: k from its own
  // degrees of freedom): where calibration.json's coverage_factor and budget are given. None
  // without budgets.
  std::optional<size_t> worst_budget_angle() const;
};

struct CalibrationReport {
  Method method = Method::differences;
  std::string source;  // the samples file
  std::string unit;
  size_t samples = 0, null_dwells = 0, offset_dwells = 0, pairs = 0;
  OutlierSummary outliers;  // frames the reduction left out of the dwell means, per axis, and its rule
  AxisFit pitch, yaw;  // pitch from counts_alpha (alpha), yaw from counts_beta (beta)
  // The reference calibration file used: its identity() and `corrected_by` ("calibrate": the rows
  // were corrected by this fit; "run": the recording was); absent without one.
  std::optional<nlohmann::json> reference;

  // The fitted set in the coefficient-file format, with residuals, uncertainties, method,
  // solver summary and source as extra keys.
  CoefficientSet coefficients() const;
};

// Throws DataError when the recording cannot determine a transfer function (naming what is
// missing), std::runtime_error when the solver fails.
CalibrationReport calibrate(const SampleTable& samples, const CalibrationOptions& opts = {});
// The fit of an existing reduction (its dwells and outlier counts).
CalibrationReport calibrate(const Reduction& reduced, const CalibrationOptions& opts, const std::string& source,
                            size_t samples);
// The fit of dwells; `outliers` counts what the dwells say and leaves the rule's noise unset.
CalibrationReport calibrate_dwells(const std::vector<Dwell>& dwells, const CalibrationOptions& opts,
                                   const std::string& source = {}, size_t samples = 0);

// How far one transfer function is from another over [lo, hi] counts, arcsec.
struct TransferDifference {
  double max_abs_arcsec = 0, rms_arcsec = 0, at_counts = 0;
};
TransferDifference compare_transfer(const AxisCoeffs& a, const AxisCoeffs& b, double lo_counts,
                                    double hi_counts, int steps = 2000);

namespace fit {
// Shared by the batch and the streaming calibrator.
enum class Axis { alpha, beta };
void add_pair_rows(AxisData& d, Axis axis, const Dwell& null_dwell, const Dwell& offset_dwell);
void add_null(AxisData& d, Axis axis, const Dwell& null_dwell);
void add_absolute_row(AxisData& d, Axis axis, const Dwell& dwell);
// Both axes' rows from the dwells, by the method set in `alpha.differences` (and beta's): one
// row per null-offset pair, in the order of the pairs returned, then every null dwell's null
// condition; or (absolute) one row per dwell, in order, and no pairs.
std::vector<DwellPair> add_dwell_rows(AxisData& alpha, AxisData& beta, const std::vector<Dwell>& dwells);
// Table 1's figures of the rows' residuals under `c` (all zero without rows).
ResidualStats residual_stats(const AxisData& d, const AxisCoeffs& c);
// DataError when the rows cannot tell this axis's coefficients apart.
void check_axis(const AxisData& d, Axis axis, const std::string& origin);
// Best grid nodes (+ the start set) -> screened refinement -> full refinement -> covariance.
AxisFit fit_axis(const AxisData& d, const FrequencyGram& gram, Axis axis, const CalibrationOptions& opts);
}  // namespace fit

}  // namespace fpss
