// Calibration procedures: declarative YAML steps (no code), parsed and validated with every error at once.
#pragma once
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/sha256.h"  // sha256_hex, for the files a run names
#include "calib/samples.h"
#include "procedures/yaml_diag.h"

namespace fpss {

enum class StandAxis { pitch = 0, yaw = 1 };
const char* to_string(StandAxis a);

// How many frames make one measurement of a point: a count, or a duration at the sample rate.
struct FrameSpec {
  int frames = 0;            // > 0 when given as a count
  double duration_s = 0;     // > 0 when given as a duration
  int max_invalid = 0;       // invalid frames tolerated per point before it is re-measured
  int count(double sample_rate_hz) const;  // frames to keep
};

struct HomeStep {
  std::optional<double> timeout_s;  // physical seconds; stand default otherwise
};

struct MoveStep {
  std::optional<double> pitch_arcsec, yaw_arcsec;  // absolute, stand frame; absent: unchanged
  std::optional<double> rate_arcsec_s;             // profile speed of this move; stand default otherwise
};

struct SettleStep {
  double duration_s = 0;
};

// One measured point at the current target (after home/move steps).
struct SampleStep {
  FrameSpec frames;
  std::optional<Phase> phase;  // default: null at (0, 0), offset elsewhere
  double settle_s = 0;         // after re-moving when the point is measured again
};

// The most points (dwells and slews) one plan may have (docs/procedures.md, Limits): 100,000
// dwells are days of stand time, and anything beyond is a typo (step_deg: 1e-7) that would
// otherwise exhaust memory.
inline constexpr size_t kMaxPlanPoints = 100000;

// The paper's pattern: null, offset, null, offset, ... every offset between two null dwells.
struct GridStep {
  // spread: coarse to fine, the extremes first, then halving the gaps (so that every prefix of
  // the grid spans the range, which an adaptive stop needs).
  enum class Order { outward, ascending, descending, spread };
  enum class Layout { axes, diagonals, full };
  std::vector<StandAxis> axes{StandAxis::pitch, StandAxis::yaw};  // axis order
  double extent_arcsec = 0;  // largest offset
  double step_arcsec = 0;    // offsets at +-step, +-2 step, ... up to +-extent
  double settle_s = 0.5;     // after in-position, before sampling (each dwell)
  FrameSpec frames;          // samples per dwell
  Order order = Order::outward;
  Layout layout = Layout::axes;
  // Offsets listed one by one, in recording order (a design from `fpss-stand design`): when one is
  // given, extent and step are not, and `axes` are the listed ones (pitch first).
  std::vector<double> pitch_offsets_arcsec, yaw_offsets_arcsec;
  // Adaptive stop (`until: {angle_sigma_max_arcsec: S}`): each axis's points end once the live
  // fit's largest 1-sigma over the grid's range is at most S; 0: every point is taken.
  double until_sigma_arcsec = 0;
  std::vector<double> offsets_arcsec() const;  // ordered, zero excluded (extent and step)
  std::vector<double> offsets_arcsec(StandAxis axis) const;  // the list of that axis, or the above
  bool listed() const { return !pitch_offsets_arcsec.empty() || !yaw_offsets_arcsec.empty(); }
};

// Turns inside one slew segment at most: a segment is one point, recorded whole in memory.
inline constexpr int kMaxSlewReversals = 20;

// Bang-bang slews along one axis between -amplitude and +amplitude, one segment per rate and direction;
// with reversals, each segment goes back and forth (the axis reverses inside the recorded segment).
struct SlewStep {
  enum class Directions { both, positive, negative };
  StandAxis axis = StandAxis::pitch;
  double amplitude_arcsec = 0;
  std::vector<double> rates_arcsec_s;
  Directions directions = Directions::both;
  double sample_period_s = 0;  // one recorded sample per period (sensor time)
  double settle_s = 0.5;       // at the start of each segment
  int reversals = 0;           // turns inside each segment: start -> far end -> start -> ... (reversals + 1 legs)
};

// Fit at this point of the procedure, on every point recorded before it.
struct CalibrateStep {
  std::string method = "differences";         // differences | absolute
  std::optional<std::filesystem::path> init;  // starting coefficient file (relative to the procedure)
  std::optional<int> max_iterations;          // the calibrator's options (calib/calibrator.h)
  std::optional<int> refine_nodes;
  std::optional<int> threads;
};

struct ResidualLimits {
  std::optional<double> mean_abs_arcsec, sd_arcsec, max_abs_arcsec;
  std::optional<int64_t> min_points;
  bool any() const { return mean_abs_arcsec || sd_arcsec || max_abs_arcsec || min_points; }
};

// Limits on the latest calibration's residuals (Table 1 form), per stand-reported axis.
struct CheckStep {
  ResidualLimits pitch, yaw;
};

// The sim-to-real diagnosis (calib/diagnosis/diagnosis.h) of every point recorded before it, against a model:
// GAP.json and GAP.html in the run folder.
struct DiagnoseStep {
  std::filesystem::path model;  // the sim's coefficient file (relative to the procedure); "" with `models`
  // Several units: each unit's sim model by serial (relative to the procedure); a unit not listed
  // takes `model` when it is given, else is not diagnosed.
  std::map<std::string, std::filesystem::path> models;
  bool partial = false;         // a recording that cannot tell every effect apart is not a warning
  double settle_s = 0;          // time from a dwell's arrival to its first sample (diagnose --settle-s)
};

using StepBody = std::variant<HomeStep, MoveStep, SettleStep, SampleStep, GridStep, SlewStep, CalibrateStep, CheckStep,
                              DiagnoseStep>;

struct Step {
  std::string type;  // as written: home, move, ...
  size_t index = 0;  // 1-based position in `steps`
  TextMark mark;
  StepBody body;
  bool valid = true;  // parsed without error (only valid steps are expanded)
};

struct Procedure {
  std::string name;         // `name:` or the file stem
  std::string description;
  std::string origin;       // file it came from, for messages
  std::string text;         // the file's text, as recorded in run.json
  std::vector<Step> steps;
};

// Every step type the format knows, for messages and docs.
const std::vector<std::string_view>& step_types();

// Parses and validates a procedure. Errors go to `d` (all of them); the result is usable only
// when d is empty.
Procedure parse_procedure(std::string_view text, const std::string& origin, Diagnostics& d);
// Reads a file; throws InputError listing every error.
Procedure load_procedure(const std::filesystem::path& path);

// The folder of the shipped procedures (discrete_grid.yaml, acceptance.yaml, the limits):
// $FPSS_PROCEDURES_DIR, else the checkout's procedures/.
std::filesystem::path shipped_procedures_dir();

}  // namespace fpss
