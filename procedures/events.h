// The engine's event stream: typed events published to subscribers (after Bluesky's documents and RunEngine callbacks).
#pragma once
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/unique_fd.h"
#include "calib/samples.h"
#include "procedures/plan.h"
#include "procedures/recorder.h"

namespace fpss {


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
// The name's cause; nullopt for any other text.
std::optional<StopCause> parse_stop_cause(std::string_view name);

// Why one unit of several on the gimbal was dropped from the rest of the run (the others go on).
enum class LossCause {
  silence,         // no frame within the frame timeout, after a restart of its stream
  crc_storm,       // its frames arrived with bad CRCs (a line fault): none usable
  invalid_frames,  // it kept sending invalid frames (no Sun, an axis invalid, saturated)
  wrong_serial,    // it reported another serial than the stand file's
  link_failed,     // its link could not be opened or reopened
};
const char* to_string(LossCause c);
std::optional<LossCause> parse_loss_cause(std::string_view name);

// Every event carries the values its events.jsonl line carries (docs/formats.md), so a line read
// back (event_from_json) is the same event; `utc` is when it was written (empty until then: the
// writer stamps it).

// A point as events name it: what the line carries of the plan's Action.
struct EventPoint {
  int64_t index = 0;                           // 0-based plan index (the line's "point" is index + 1)
  size_t step_index = 0;                       // the procedure step it came from (1-based)
  Action::Kind kind = Action::Kind::dwell;     // dwell or slew
  Phase phase = Phase::null;
  double target_pitch_arcsec = 0, target_yaw_arcsec = 0;  // stand frame
  static EventPoint of(const Action& a);
  bool operator==(const EventPoint&) const = default;
};
// A point of the plan as RunStarted lists it.
struct PlannedPoint {
  int64_t index = 0;  // 0-based
  double target_pitch_arcsec = 0, target_yaw_arcsec = 0;
  bool operator==(const PlannedPoint&) const = default;
};
// One point's rows, shared by its Samples and PointDone events (made once, never copied per event).
using SharedRows = std::shared_ptr<const std::vector<RecordedRow>>;

// A run begins (or resumes): what will be done.
struct RunStarted {
  int session = 1;
  int64_t first_point = 0;       // 0-based plan index of the first point still to measure
  size_t points_total = 0;       // the plan's points
  double estimated_s = 0;        // the dry run's estimate (physical seconds)
  std::vector<PlannedPoint> points;  // every point of the plan, in order
  std::string utc;
  static RunStarted of(int session, int64_t first_point, const Plan& plan);
};
// A point's measurement begins (each attempt).
struct PointStarted {
  EventPoint point;
  int attempt = 1;
  std::string utc;
};
// The rows of one point, before they are durable: the recorder makes them so.
struct Samples {
  EventPoint point;
  SharedRows rows;       // null when read back from events.jsonl (the rows are in samples.csv)
  size_t row_count = 0;  // rows->size() when there are rows
  int attempt = 1, session = 1;
  std::string utc;
};
// Means and scatter of one point's rows.
struct PointStats {
  size_t rows = 0;
  double ref_pitch_arcsec = 0, ref_yaw_arcsec = 0;  // mean reference (sensor frame)
  double counts_alpha = 0, counts_beta = 0;         // mean counts
  double sd_counts_alpha = 0, sd_counts_beta = 0;   // sample standard deviation
  static PointStats of(const std::vector<RecordedRow>& rows);
  bool operator==(const PointStats&) const = default;
};
// A point is measured and durable.
struct PointDone {
  EventPoint point;
  SharedRows rows;  // null when read back from events.jsonl
  PointStats stats;
  int attempts = 1;
  int invalid_frames = 0;  // frames skipped as invalid in the attempt that was kept
  double temperature_c = std::numeric_limits<double>::quiet_NaN();  // the sensor's; NaN: it did not answer
  bool valid = true;
  std::string utc{};
};
// The streaming estimate after a point (published by whoever runs the estimator). NaN: not known.
struct FitUpdated {
  int64_t points = 0;
  size_t pairs = 0;
  double rms_pitch_arcsec = 0, rms_yaw_arcsec = 0;      // residual of the changes
  double sigma_max_pitch_arcsec = 0, sigma_max_yaw_arcsec = 0;  // 1-sigma of the fitted angle, worst over the range
  std::string utc;
};
// A grid's adaptive stop reached its target: the rest of one group's points will not be measured.
struct StepStopped {
  size_t step_index = 0;           // the procedure step (1-based)
  std::string axes;                // "pitch", "yaw" or "both": whose points end
  double sigma_max_arcsec = 0;     // the live fit's largest 1-sigma over the grid's range
  double until_sigma_arcsec = 0;   // the step's target
  std::vector<int64_t> skipped;    // points (0-based) not measured, in order
  int session = 1;
  std::string utc;
  std::string reason() const;      // the line's "reason", made from the figures above
};
struct Paused {
  int64_t next_point = 0;
  std::string utc;
};
struct Resumed {
  int64_t next_point = 0;
  std::string utc;
};
// Something went wrong but the run goes on (a re-measurement, a recovery) or a note worth seeing.
struct Fault {
  enum class Level { warning, fault } level = Level::warning;
  int64_t point = -1;  // 0-based; -1 when not about one point
  std::string message;
  std::string utc;
};
struct RunStopped {
  RunOutcome outcome = RunOutcome::completed;
  StopCause cause = StopCause::none;
  std::string reason;
  int64_t points_done = 0;
  bool safe_state = true;
  std::string utc;
};

using Event = std::variant<RunStarted, PointStarted, Samples, PointDone, FitUpdated, StepStopped, Paused, Resumed, Fault,
                           RunStopped>;

// One line of events.jsonl (docs/formats.md): {"type": ..., "utc": ..., ...}; point numbers 1-based.
// The event's utc, or now when it has none.
nlohmann::ordered_json to_json(const Event& e);

// A line of events.jsonl that is not an engine event: what the run session adds (an operator's
// prompt and its answer, EventLog::write_note; a point's residual against the live fit). Its type
// is one of note_types(); `body` holds its other keys as written.
struct Note {
  std::string type, utc;
  nlohmann::ordered_json body = nlohmann::ordered_json::object();
};
// "point_residual", "prompt", "prompt_answered", "prompt_rejected".
const std::vector<std::string>& note_types();
using EventLine = std::variant<Event, Note>;

// The typed form of one line: an engine event (to_json(event_from_json(l)) == l for every line
// the engine writes) or a Note. InputError "<origin>: key \"k\": ..." naming the key for a line
// that is neither: not an object, an unknown type, a key missing or of the wrong type or range.
EventLine event_line_from_json(const nlohmann::json& line, const std::string& origin);
// An engine event; a Note is an InputError too.
Event event_from_json(const nlohmann::json& line, const std::string& origin);

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

// Reading events.jsonl back, as a hostile input: the file at most kMaxTextFileBytes, a line at most
// kMaxEventLineBytes (a plan of 100,000 points is about 5 MB on its run_started line), each line
// through the one JSON parser (base/json_file.h). A bad line is an InputError naming the file, the
// line number and the key; a last line without its newline (a write cut short) is left out.
inline constexpr size_t kMaxEventLineBytes = size_t{16} << 20;  // 16 MiB
// Calls `f` with each line's typed form, in order.
void read_event_lines(const std::filesystem::path& path, const std::function<void(EventLine&&)>& f);
// Replays a run's events.jsonl: publishes its engine events to `bus` in the order they were
// written (every session of the run), so subscribers (a summary, a chart) can be driven from a
// finished run as they were live. Notes go to `on_note` when given. Replayed Samples and PointDone
// carry no rows (null `rows`): the rows are in samples.csv.
struct ReplayCount {
  size_t events = 0, notes = 0;
};
ReplayCount replay_events(const std::filesystem::path& path, const EventBus& bus,
                          const std::function<void(const Note&)>& on_note = {});

}  // namespace fpss
