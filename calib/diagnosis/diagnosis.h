// Sim-to-real gap diagnosis: which unmodelled bench effect explains model(counts) - reference, checked on held-out steps.
#pragma once
#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "calib/reduction.h"
#include "calib/samples.h"

namespace fpss {

// The candidate effects, named exactly as the emulator's --effect option (docs/emulator.md).
const std::vector<std::string>& diagnosis_effect_names();

// One effect with parameters in the emulator's names, conventions and units. The coefficients
// effect carries the sensor's true transfer function instead of numbers.
struct EffectParams {
  std::string name;
  std::map<std::string, double> params;
  std::optional<CoefficientSet> coefficients;
};

// The calibrated half-range a diagnosis accepts (DiagnosisOptions::calibrated_range_arcsec), arcsec:
// 0.1 deg to 10 deg.
inline constexpr double kMinCalibratedRangeArcsec = 360, kMaxCalibratedRangeArcsec = 36000;
// The sixths of the calibrated range (±calibrated_range_arcsec) a recording's usable rows reach, per
// axis (pitch, yaw; from the low end up): where a refitted transfer function is measured rather than
// extrapolated.
inline constexpr int kRangeSections = 6;
using RangeSections = std::array<std::array<bool, kRangeSections>, 2>;

struct DiagnosisOptions {
  // Time from a dwell's arrival (in-position) to its first sample, when no time_since_move_s
  // column says it; settling amplitudes refer to the arrival.
  double settle_s = 0.0;
  // time_skew is searched within +-max_skew_s; the first and last max_skew_s of every slew
  // segment are left out of every score (the reference outside a segment is not recorded).
  double max_skew_s = 0.25;
  // One step in `heldout_every` of each kind (dwells, slews) is held out.
  int heldout_every = 3;
  bool second_effect = true;
  // A second effect is looked for only while the first leaves more than this times the noise floor
  // (held out or on the fit rows).
  double second_effect_gap_ratio = 1.2;
  // Dwell rows less than this after their arrival are left out of every fit, score and noise
  // estimate: a sensor that lags the reference (a time skew) still shows the end of the move there,
  // whose path the recording does not hold (as at the ends of a slew segment). One frame at 50 Hz:
  // a recording sampled from arrival loses its first frame of each dwell.
  double arrival_guard_s = 0.02;
  // The calibrated half-range, arcsec (the paper's grid, ±0.42 deg): a refitted transfer function
  // is pinned over it where its rows reach every sixth of it on both axes (docs/diagnosis.md).
  double calibrated_range_arcsec = 1512;
  // What an investigation calls material (arcsec; docs/diagnosis.md, "Investigation"): 0 for the
  // noise floor of one dwell mean. Only the candidates' status uses it.
  double materiality_arcsec = 0;
  // How the recording's one reduction judges the frames of null and offset dwells (the count
  // noise under the outlier rule's floor, when the stand knows it).
  ReductionOptions reduction;
};

struct WhereEntry {
  std::string factor;  // constant, angle, cross_angle, slew_rate, approach_direction, time, time_since_move, temperature
  std::string axis;    // pitch, yaw, both
  double share = 0;    // part of the held-out gap's mean square this factor accounts for
  std::string detail;
};

struct EffectResult {
  std::string name;
  nlohmann::ordered_json params;  // emulator names and units
  int parameters = 0;             // free parameters fitted
  double fit_rms_arcsec = 0;      // on the fit rows
  double heldout_rms_arcsec = 0;  // on the held-out rows
  double score = 0;               // selection score, lower is better (none = 0)
  nlohmann::ordered_json notes = nlohmann::ordered_json::object();
  std::string degenerate;         // why the fit is ill-conditioned/implausible; never the cause then
  // The smallest magnitude of each parameter this recording would have made material (its own
  // units; coefficients: angle_rms_arcsec, the RMS change of the angle over the calibrated range);
  // empty for none.
  nlohmann::ordered_json detection_limit = nlohmann::ordered_json::object();
  // The same for what the data can see at all (the expected score equals none's: the penalty is
  // paid), without the naming rule's floor: what bounds an effect that is not named.
  nlohmann::ordered_json statistical_limit = nlohmann::ordered_json::object();
  // That limit as arcsec: the effect's RMS where it acts, at the limit (+inf when the recording
  // cannot see it); an investigation bounds a candidate when this is below its materiality.
  double limit_arcsec = std::numeric_limits<double>::infinity();
};

struct NotObservable {
  std::string name;
  std::string reason;
  bool incomplete_recording = false;  // the recording lacks a part every diagnosis recording should have
};

// The clock a joint diagnosis's recording runs on: `bench`, shifted by its time_shift_s onto the
// first recording's gimbal clock; `recorded`, its time_s already going on from the recording before
// (as one lab clock writes it); `own`, starting again (time_shift_s NaN; it keeps a level of its own).
enum class JointClock { bench, recorded, own };
const char* to_string(JointClock c);  // GAP.json `recordings[].clock`

struct Diagnosis {
  std::string source;
  std::string cause = "none";
  std::vector<EffectResult> causes;  // in order; empty for none
  double gap_before_arcsec = 0;
  double gap_after_arcsec = 0;      // the first cause alone
  double gap_after_all_arcsec = 0;  // every cause in `causes`
  double noise_floor_arcsec = 0;
  // The default materiality of an investigation: the noise floor of one dwell mean (the frame's
  // floor over the root of the median frames per dwell).
  double materiality_arcsec = 0;
  // The half-range a refitted transfer function is judged measured over (DiagnosisOptions').
  double calibrated_range_arcsec = 0;
  std::vector<WhereEntry> where;        // before any effect is added
  std::vector<WhereEntry> where_after;  // what is left once the causes are added
  std::vector<EffectResult> effects;    // every candidate tried, best first
  std::vector<NotObservable> not_observable;
  // Every catalogued candidate against the end state of an investigation (calib/diagnosis/followup.h:
  // named, bounded, immaterial, ambiguous or unbounded) and the context its material magnitudes
  // come from (the recordings' fastest slew, recorded time, half-range, temperature span).
  nlohmann::ordered_json candidates = nlohmann::ordered_json::array();
  nlohmann::ordered_json material_context = nlohmann::ordered_json::object();
  // Candidates that score almost as well as the cause: the data barely tells them apart.
  struct Ambiguity {
    std::string name;
    double score_difference = 0;
    std::string why;
  };
  std::vector<Ambiguity> ambiguous_with;
  // Sets of candidates this recording cannot tell apart (docs/diagnosis.md, "When one recording
  // cannot tell"): the cause and every single candidate whose held-out score lies within
  // kAmbiguityMargin of it, and look-alikes the recording cannot score at all (a temperature that
  // follows time beside drift, a one-sided approach's backlash beside a bias).
  struct AmbiguousSet {
    std::vector<std::string> members;       // the cause first
    std::vector<double> score_differences;  // each member's score less the cause's; NaN: not scored
    std::string factor;                     // the `where` factor along which their predictions part
    std::string measurement;                // the kind of run that separates them
    std::string why;
    // The best follow-up's predicted separation (stand/design): null until a designer fills it.
    nlohmann::ordered_json best_followup;
  };
  std::vector<AmbiguousSet> ambiguous;
  nlohmann::ordered_json split;
  nlohmann::ordered_json recording;  // what the data holds: rows, steps, spans
  // Each recording of a joint diagnosis (one entry for a single recording): its nuisance levels.
  struct Part {
    std::string source;
    size_t rows = 0;
    int64_t step_offset = 0;
    double time_span_s[2] = {0, 0};  // on the joint clock
    double time_shift_s = std::numeric_limits<double>::quiet_NaN();  // onto the bench clock; NaN: own clock
    JointClock clock = JointClock::recorded;
    double noise_floor_arcsec = 0;
  };
  std::vector<Part> recordings;
  std::vector<std::string> warnings;

  // no_gap | explained | partly_explained | unexplained (docs/diagnosis.md)
  std::string verdict = "no_gap";
  std::string verdict_sentence;  // the verdict in one plain sentence
  // Present when verdict is partly_explained or unexplained: what stays after the causes.
  struct Remainder {
    double heldout_rms_arcsec = 0;
    std::vector<WhereEntry> where;
    nlohmann::ordered_json flexible_shrink = nlohmann::ordered_json::object();
  };
  std::optional<Remainder> unexplained;
  // Within-step scatter of one sample about its step mean after the causes (dwells), and the
  // model file's expected_scatter_arcsec when it has one.
  double within_step_scatter_arcsec = std::numeric_limits<double>::quiet_NaN();
  double expected_scatter_arcsec = std::numeric_limits<double>::quiet_NaN();
  double excess_scatter() const { return within_step_scatter_arcsec / expected_scatter_arcsec; }
  // Isolated frames far from their step's robust estimate, kept out of every fit.
  int64_t outliers = 0;
  double outlier_fraction = 0;
  int64_t outliers_pitch = 0, outliers_yaw = 0;  // flagged on that axis (a frame may be on both)
  int64_t frames = 0;                            // rows the fractions are of
  std::vector<int64_t> outlier_steps;
  // The null and offset dwells' outlier frames as the recording's one reduction counts them (the
  // numbers calibration.json and acceptance.json give for the same rows).
  OutlierSummary dwell_outliers;

  bool incomplete_recording() const;
  // GAP.json
  nlohmann::ordered_json to_json() const;
};

// One recording of a joint diagnosis as joined: where it came from, its rows, its clock.
struct JointPart {
  std::string origin;
  size_t rows = 0;
  double time_shift_s = std::numeric_limits<double>::quiet_NaN();
  JointClock clock = JointClock::own;
};

// The columns the diagnosis reads, column-major and nothing else (about 60 bytes a row): the
// samples file's required columns but `phase` (labels are not trusted), and temperature_c,
// time_since_move_s and approach_pitch/approach_yaw (the side each axis last came from, in the
// recording's frame) when the recording has them (empty otherwise).
struct DiagnosisColumns {
  std::string origin;
  std::vector<double> time_s, ref_pitch_arcsec, ref_yaw_arcsec, counts_alpha, counts_beta;
  std::vector<int64_t> step;
  std::vector<float> temperature_c, time_since_move_s;
  std::vector<float> approach_pitch, approach_yaw;  // +1, -1, 0 (no motion yet), NaN (moving)
  // The recordings joined into these columns (join_recordings), in order; empty for a single one.
  std::vector<JointPart> parts;
  // The bench's (gimbal's) clock at this recording's time_s = 0: gimbal_time_s - time_s at its
  // first row with both (NaN without a gimbal_time_s column). A joint diagnosis puts recordings
  // on one bench clock with it.
  double bench_clock_s = std::numeric_limits<double>::quiet_NaN();
  size_t size() const { return time_s.size(); }
  static DiagnosisColumns of(const SampleTable& t);  // a copy of the columns the diagnosis reads
};

// Reads a samples CSV straight into those columns, in chunks (the checks and messages of
// read_samples_csv; no other column is held). Rows of steps after `last_step` are left out.
DiagnosisColumns read_diagnosis_columns(const std::filesystem::path& path,
                                        int64_t last_step = std::numeric_limits<int64_t>::max());

struct DiagnosisFigures;

// Two candidates are ambiguous when their held-out scores (-2 ln likelihood, up to constants)
// differ by less than this: a likelihood ratio below e^5 (about 150). The ambiguity of the scores
// is the sampling spread of a realised log-likelihood ratio, whose standard deviation is
// sqrt(2 x its mean) for Gaussian residuals; 5 is where a chance preference of one look-alike
// over another becomes rare (docs/diagnosis.md).
inline constexpr double kAmbiguityMargin = 10.0;

// Several recordings of one unit diagnosed as one (diagnose --data A --data B ...): one effect
// with one set of parameters must explain every recording, and each keeps its own nuisance
// levels: its own arrival clock and its own noise floor (GAP.json `recordings`). Time runs on one
// bench clock when every recording has gimbal_time_s and the gimbal's clock went on between them
// (recording k's time_s shifted by its bench_clock_s less the first's: drift and temperature then
// see the time between runs, as a bench whose environment goes on does); otherwise each recording
// runs on its time_s as recorded: one clock when each recording starts after the one before it
// ended, else each its own from its own time_s = 0 (a warning says so).
// Recording k's (0-based) step ids are offset by k x kJointStepStride so that steps of different
// recordings never merge; the held-out split runs over the joined steps in order, so it spans the
// recordings. At most kMaxJointRecordings. A time_since_move_s column is used only when every
// recording has it (a warning says so otherwise); temperature_c is NaN where a recording lacks it.
inline constexpr int64_t kJointStepStride = 1000000;
inline constexpr size_t kMaxJointRecordings = 16;
DiagnosisColumns join_recordings(std::vector<DiagnosisColumns> parts);

// Throws InputError/DataError naming what cannot be told apart when the recording cannot
// support any diagnosis (no rows, a single dwell, counts the model cannot map). The columns are
// taken over (not copied); `figures`, when given, gets the report's data (diagnosis_figures).
Diagnosis diagnose(DiagnosisColumns data, const CoefficientSet& model, const DiagnosisOptions& opts = {},
                   DiagnosisFigures* figures = nullptr);
Diagnosis diagnose(const SampleTable& data, const CoefficientSet& model, const DiagnosisOptions& opts = {});
// Several recordings jointly (join_recordings).
Diagnosis diagnose(std::vector<DiagnosisColumns> recordings, const CoefficientSet& model,
                   const DiagnosisOptions& opts = {}, DiagnosisFigures* figures = nullptr);

// The forward model: what the sensor would read (pitch, yaw arcsec per row, through the model's
// transfer function) given the recording's reference angles and times, with `effect` applied
// under the emulator's conventions. For `coefficients` the sensor's counts come from the
// effect's transfer function and are mapped back through `model`.
struct SensorPrediction {
  std::vector<double> pitch_arcsec, yaw_arcsec;
  std::vector<bool> predictable;  // false where the data cannot say (e.g. skewed time outside a segment)
};
SensorPrediction predict_sensor(const SampleTable& data, const CoefficientSet& model, const EffectParams& effect,
                                const DiagnosisOptions& opts = {});

// What the report shows, as data (calib writes no HTML and runs no plotter; the page is
// stand/report/diagnosis_page.h): the residual of each axis against every factor, before and
// after the causes, on scored rows (at most ~20000, evenly strided), and the residual map over
// the field (one point per dwell: its mean reference and mean residual before and after).
struct DiagnosisFactorSeries {
  std::string factor;  // angle, cross_angle, slew_rate, approach_direction, time, time_since_move, temperature
  std::string xlabel;
  std::vector<double> x[2], before[2], after[2];  // per axis (0 pitch, 1 yaw)
};
struct DiagnosisMapPoint {
  double pitch_arcsec = 0, yaw_arcsec = 0;
  double before[2] = {0, 0}, after[2] = {0, 0};
};
struct DiagnosisFigures {
  std::vector<DiagnosisFactorSeries> factors;
  std::vector<DiagnosisMapPoint> map;
};
DiagnosisFigures diagnosis_figures(const SampleTable& data, const CoefficientSet& model, const Diagnosis& d,
                                   const DiagnosisOptions& opts = {});

// Writes a GAP.json (a diagnosis, a joint one, an investigation's last) atomically: the one layout
// every writer uses, so that two files of the same diagnosis are the same bytes.
void write_gap_file(const std::filesystem::path& path, const nlohmann::ordered_json& j);

}  // namespace fpss
