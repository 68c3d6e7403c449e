// The engine's event stream: typed events published to subscribers (after Bluesky's documents and RunEngine callbacks).
#pragma once
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/unique_fd.h"
#include "procedures/recorder.h"

namespace fpss {

struct Action;
struct Plan;

enum class RunOutcome { completed, failed, interrupted };
const char* to_string(RunOutcome o);
// The name's outcome; nullopt for any other text.
std::optional<RunOutcome> parse_outcome(std::string_view name);

// Why a run stopped: decided where the failure is caught, never by reading a message.
enum class StopCause {
  none,                 // completed
  interrupted,          // SIGINT/SIGTERM
  aborted,              // the operator asked (RunControl::abort without a signal)
  sensor_invalid,       // the sensor kept sending invalid frames (no Sun, an axis invalid, saturated)
  sensor_timeout,       // the sensor stopped sending frames or answering
  gimbal_fault,         // the gimbal faulted, did not arrive, or left the point
  limit,                // a target beyond the soft limits (refused before the wire)
  commanded_elsewhere,  // the gimbal was commanded by another client
  check_failed,         // a check step's limits were broken
  calibration_failed,   // a calibrate step could not fit
  diagnosis_failed,     // a diagnose step could not diagnose
  storage,              // the recording could not be made durable
  unsafe,               // the run ended but the gimbal could not be returned to null
  other,                // anything else (the reason says what)
};
const char* to_string(StopCause c);

// A run begins (or resumes): what will be done.
struct RunStarted {
  int session = 1;
  int64_t first_point = 0;       // 0-based plan index of the first point still to measure
  const Plan* plan = nullptr;
};
// A point's measurement begins (each attempt).
struct PointStarted {
  const Action* action = nullptr;
  int attempt = 1;
};
// The rows of one point, before they are durable: the recorder makes them so.
struct Samples {
  const Action* action = nullptr;
  const std::vector<RecordedRow>* rows = nullptr;
  int attempt = 1, session = 1;
};
// Means and scatter of one point's rows.
struct PointStats {
  size_t rows = 0;
  double ref_pitch_arcsec = 0, ref_yaw_arcsec = 0;  // mean reference (sensor frame)
  double counts_alpha = 0, counts_beta = 0;         // mean counts
  double sd_counts_alpha = 0, sd_counts_beta = 0;   // sample standard deviation
  static PointStats of(const std::vector<RecordedRow>& rows);
};
// A point is measured and durable.
struct PointDone {
  const Action* action = nullptr;
  const std::vector<RecordedRow>* rows = nullptr;
  PointStats stats;
  int attempts = 1;
  int invalid_frames = 0;  // frames skipped as invalid in the attempt that was kept
};
// The streaming estimate after a point (published by whoever runs the estimator).
struct FitUpdated {
  int64_t points = 0;
  size_t pairs = 0;
  double rms_pitch_arcsec = 0, rms_yaw_arcsec = 0;      // residual of the changes
  double sigma_max_pitch_arcsec = 0, sigma_max_yaw_arcsec = 0;  // 1-sigma of the fitted angle, worst over the range
};
// A grid's adaptive stop reached its target: the rest of one group's points will not be measured.
struct StepStopped {
  size_t step_index = 0;           // the procedure step (1-based)
  std::string axes;                // "pitch", "yaw" or "both": whose points end
  double sigma_max_arcsec = 0;     // the live fit's largest 1-sigma over the grid's range
  double until_sigma_arcsec = 0;   // the step's target
  std::vector<int64_t> skipped;    // points (0-based) not measured, in order
  int session = 1;
};
struct Paused {
  int64_t next_point = 0;
};
struct Resumed {
  int64_t next_point = 0;
};
// Something went wrong but the run goes on (a re-measurement, a recovery) or a note worth seeing.
struct Fault {
  enum class Level { warning, fault } level = Level::warning;
  int64_t point = -1;  // 0-based; -1 when not about one point
  std::string message;
};
struct RunStopped {
  RunOutcome outcome = RunOutcome::completed;
  StopCause cause = StopCause::none;
  std::string reason;
  int64_t points_done = 0;
  bool safe_state = true;
};

using Event = std::variant<RunStarted, PointStarted, Samples, PointDone, FitUpdated, StepStopped, Paused, Resumed, Fault,
                           RunStopped>;

// One line of events.jsonl (docs/formats.md): {"type": ..., "utc": ..., ...}; point numbers 1-based.
nlohmann::ordered_json to_json(const Event& e);

// Subscribers are called in the order they subscribed, on the publishing thread. An exception
// from a subscriber propagates to the publisher: the recorder failing to make a point durable
// fails the run. A subscriber may publish (the live fit publishes FitUpdated from PointDone).
class EventBus {
 public:
  using Subscriber = std::function<void(const Event&)>;
  void subscribe(Subscriber s) { subs_.push_back(std::move(s)); }
  void publish(const Event& e) const {
    for (size_t i = 0; i < subs_.size(); ++i) subs_[i](e);
  }

 private:
  std::vector<Subscriber> subs_;
};

// Subscribes `rec` to `bus`: every Samples event's rows are appended and synced, then journalled.
void record_with(EventBus& bus, RunRecorder& rec);

// events.jsonl: one JSON object per event, appended and flushed (not fsynced: samples.csv and the
// journal are the durable record; this is the live view). Samples events are written as a count.
class EventLog {
 public:
  explicit EventLog(const std::filesystem::path& path);
  void write(const Event& e);
  // A line that is not an engine event (an operator prompt and its answer, docs/console.md):
  // {"type": type, "utc": ..., ...body}.
  void write_note(const std::string& type, const nlohmann::ordered_json& body);

 private:
  void append(const std::string& line);
  UniqueFd fd_;
  std::filesystem::path path_;
};

}  // namespace fpss
