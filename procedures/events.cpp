#include "procedures/events.h"

#include <fcntl.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "base/clock.h"
#include "procedures/plan.h"

namespace fpss {

const char* to_string(RunOutcome o) {
  switch (o) {
    case RunOutcome::completed: return "completed";
    case RunOutcome::failed: return "failed";
    case RunOutcome::interrupted: return "interrupted";
  }
  return "?";
}

std::optional<RunOutcome> parse_outcome(std::string_view name) {
  for (const RunOutcome o : {RunOutcome::completed, RunOutcome::failed, RunOutcome::interrupted}) {
    if (name == to_string(o)) return o;
  }
  return std::nullopt;
}

const char* to_string(StopCause c) {
  switch (c) {
    case StopCause::none: return "none";
    case StopCause::interrupted: return "interrupted";
    case StopCause::aborted: return "aborted";
    case StopCause::sensor_invalid: return "sensor_invalid";
    case StopCause::sensor_timeout: return "sensor_timeout";
    case StopCause::gimbal_fault: return "gimbal_fault";
    case StopCause::limit: return "limit";
    case StopCause::commanded_elsewhere: return "commanded_elsewhere";
    case StopCause::check_failed: return "check_failed";
    case StopCause::calibration_failed: return "calibration_failed";
    case StopCause::diagnosis_failed: return "diagnosis_failed";
    case StopCause::storage: return "storage";
    case StopCause::unsafe: return "unsafe";
    case StopCause::other: return "other";
  }
  return "?";
}

const char* to_string(LossCause c) {
  switch (c) {
    case LossCause::silence: return "silence";
    case LossCause::crc_storm: return "crc_storm";
    case LossCause::invalid_frames: return "invalid_frames";
    case LossCause::wrong_serial: return "wrong_serial";
    case LossCause::link_failed: return "link_failed";
  }
  return "?";
}

std::optional<LossCause> parse_loss_cause(std::string_view name) {
  for (int i = 0; i <= static_cast<int>(LossCause::link_failed); ++i) {
    if (name == to_string(static_cast<LossCause>(i))) return static_cast<LossCause>(i);
  }
  return std::nullopt;
}

std::optional<StopCause> parse_stop_cause(std::string_view name) {
  for (int i = 0; i <= static_cast<int>(StopCause::other); ++i) {
    if (name == to_string(static_cast<StopCause>(i))) return static_cast<StopCause>(i);
  }
  return std::nullopt;
}

EventPoint EventPoint::of(const Action& a) {
  return {a.point, a.step_index, a.kind == Action::Kind::slew ? Action::Kind::slew : Action::Kind::dwell, a.phase,
          a.pitch_arcsec, a.yaw_arcsec};
}

RunStarted RunStarted::of(int session, int64_t first_point, const Plan& plan) {
  RunStarted r;
  r.session = session;
  r.first_point = first_point;
  r.points_total = plan.points;
  r.estimated_s = plan.estimated_s;
  r.points.reserve(plan.point_action.size());
  for (size_t i : plan.point_action) {
    const Action& a = plan.actions[i];
    r.points.push_back({a.point, a.pitch_arcsec, a.yaw_arcsec});
  }
  return r;
}

std::string StepStopped::reason() const {
  return fmt::format("adaptive stop: the live fit's largest 1-sigma {:.4f} arcsec is at most the target {:.4f} arcsec",
                     sigma_max_arcsec, until_sigma_arcsec);
}

PointStats PointStats::of(const std::vector<RecordedRow>& all) {
  PointStats s;
  if (all.empty()) return s;
  // Several units: the lead's rows (the first unit's in the point) describe the point.
  std::vector<const RecordedRow*> rows;
  for (const auto& r : all) {
    if (r.unit == all.front().unit) rows.push_back(&r);
  }
  s.rows = rows.size();
  for (const RecordedRow* r : rows) {
    s.ref_pitch_arcsec += r->sample.ref_pitch_arcsec;
    s.ref_yaw_arcsec += r->sample.ref_yaw_arcsec;
    s.counts_alpha += r->sample.counts_alpha;
    s.counts_beta += r->sample.counts_beta;
  }
  const double n = static_cast<double>(rows.size());
  s.ref_pitch_arcsec /= n;
  s.ref_yaw_arcsec /= n;
  s.counts_alpha /= n;
  s.counts_beta /= n;
  if (rows.size() > 1) {
    double va = 0, vb = 0;
    for (const RecordedRow* r : rows) {
      va += (r->sample.counts_alpha - s.counts_alpha) * (r->sample.counts_alpha - s.counts_alpha);
      vb += (r->sample.counts_beta - s.counts_beta) * (r->sample.counts_beta - s.counts_beta);
    }
    s.sd_counts_alpha = std::sqrt(va / (n - 1));
    s.sd_counts_beta = std::sqrt(vb / (n - 1));
  }
  return s;
}

namespace {

using ojson = nlohmann::ordered_json;

std::string utc_now_ms() {
  const auto now = std::chrono::system_clock::now();
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  const std::string s = utc_now_iso();  // ...SSZ
  return fmt::format("{}.{:03d}Z", s.substr(0, s.size() - 1), ms);
}

// A point as the outside sees it: 1-based number, the step it came from, its target.
ojson point_json(const EventPoint& p) {
  ojson j;
  j["point"] = p.index + 1;
  j["step"] = p.step_index;
  j["kind"] = p.kind == Action::Kind::slew ? "slew" : "dwell";
  j["phase"] = std::string(to_string(p.phase));
  j["target_pitch_arcsec"] = p.target_pitch_arcsec;
  j["target_yaw_arcsec"] = p.target_yaw_arcsec;
  return j;
}

ojson finite_or_null(double v) { return std::isfinite(v) ? ojson(v) : ojson(nullptr); }

struct ToJson {
  ojson operator()(const RunStarted& e) const {
    ojson j{{"type", "run_started"}, {"session", e.session}, {"first_point", e.first_point + 1}};
    j["points_total"] = e.points_total;
    j["estimated_s"] = e.estimated_s;
    ojson pts = ojson::array();
    for (const auto& p : e.points) pts.push_back({p.index + 1, p.target_pitch_arcsec, p.target_yaw_arcsec});
    j["points"] = std::move(pts);  // [point, target_pitch_arcsec, target_yaw_arcsec]
    return j;
  }
  ojson operator()(const PointStarted& e) const {
    ojson j{{"type", "point_started"}};
    j.update(point_json(e.point));
    j["attempt"] = e.attempt;
    return j;
  }
  ojson operator()(const Samples& e) const {
    ojson j{{"type", "samples"}};
    j.update(point_json(e.point));
    j["rows"] = e.rows ? e.rows->size() : e.row_count;
    j["attempt"] = e.attempt;
    j["session"] = e.session;
    return j;
  }
  ojson operator()(const PointDone& e) const {
    ojson j{{"type", "point_done"}};
    j.update(point_json(e.point));
    j["rows"] = e.stats.rows;
    j["ref_pitch_arcsec"] = e.stats.ref_pitch_arcsec;
    j["ref_yaw_arcsec"] = e.stats.ref_yaw_arcsec;
    j["counts_alpha"] = e.stats.counts_alpha;
    j["counts_beta"] = e.stats.counts_beta;
    j["sd_counts_alpha"] = e.stats.sd_counts_alpha;
    j["sd_counts_beta"] = e.stats.sd_counts_beta;
    j["attempts"] = e.attempts;
    j["invalid_frames"] = e.invalid_frames;
    j["temperature_c"] = finite_or_null(e.temperature_c);
    j["valid"] = e.valid;
    return j;
  }
  ojson operator()(const FitUpdated& e) const {
    return {{"type", "fit_updated"},
            {"points", e.points},
            {"pairs", e.pairs},
            {"rms_pitch_arcsec", finite_or_null(e.rms_pitch_arcsec)},
            {"rms_yaw_arcsec", finite_or_null(e.rms_yaw_arcsec)},
            {"sigma_max_pitch_arcsec", finite_or_null(e.sigma_max_pitch_arcsec)},
            {"sigma_max_yaw_arcsec", finite_or_null(e.sigma_max_yaw_arcsec)}};
  }
  ojson operator()(const StepStopped& e) const {
    ojson skipped = ojson::array();
    for (int64_t p : e.skipped) skipped.push_back(p + 1);
    return {{"type", "step_stopped"},
            {"step", e.step_index},
            {"axes", e.axes},
            {"sigma_max_arcsec", finite_or_null(e.sigma_max_arcsec)},
            {"until_sigma_arcsec", e.until_sigma_arcsec},
            {"points_skipped", e.skipped.size()},
            {"first_skipped_point", e.skipped.empty() ? ojson(nullptr) : ojson(e.skipped.front() + 1)},
            {"reason", e.reason()},
            {"skipped_points", std::move(skipped)},
            {"session", e.session}};
  }
  ojson operator()(const Paused& e) const { return {{"type", "paused"}, {"next_point", e.next_point + 1}}; }
  ojson operator()(const Resumed& e) const { return {{"type", "resumed"}, {"next_point", e.next_point + 1}}; }
  ojson operator()(const Fault& e) const {
    ojson j{{"type", e.level == Fault::Level::fault ? "fault" : "warning"}};
    j["point"] = e.point >= 0 ? ojson(e.point + 1) : ojson(nullptr);
    j["message"] = e.message;
    return j;
  }
  ojson operator()(const RunStopped& e) const {
    return {{"type", "run_stopped"},     {"outcome", to_string(e.outcome)}, {"cause", to_string(e.cause)},
            {"reason", e.reason},        {"points_done", e.points_done},    {"safe_state", e.safe_state}};
  }
};

}  // namespace

nlohmann::ordered_json to_json(const Event& e) {
  ojson body = std::visit(ToJson{}, e);
  const std::string& utc = std::visit([](const auto& x) -> const std::string& { return x.utc; }, e);
  ojson j{{"type", body["type"]}, {"utc", utc.empty() ? utc_now_ms() : utc}};
  body.erase("type");
  j.update(body);
  return j;
}

void record_with(EventBus& bus, RunRecorder& rec) {
  bus.subscribe([&rec](const Event& e) {
    if (const auto* s = std::get_if<Samples>(&e)) {
      if (!s->rows) throw std::logic_error("record_with: a Samples event without its rows (a replayed one?)");
      rec.append_point(s->point.index, *s->rows, s->attempt, s->session);
    }
    if (const auto* s = std::get_if<StepStopped>(&e)) {
      for (int64_t p : s->skipped) rec.skip_point(p, s->session, "until");
    }
  });
}

EventLog::EventLog(const std::filesystem::path& path) : path_(path) {
  fd_.reset(::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC | O_NOFOLLOW, 0644));
  if (!fd_) throw std::runtime_error(fmt::format("{}: cannot open: {}", path.string(), std::strerror(errno)));
}

void EventLog::write(const Event& e) {
  append(to_json(e).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
}

void EventLog::write_note(const std::string& type, const nlohmann::ordered_json& body) {
  ojson j{{"type", type}, {"utc", utc_now_ms()}};
  j.update(body);
  append(j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
}

void EventLog::append(const std::string& line) {
  // One write per line on an O_APPEND descriptor: a reader never sees two events interleaved.
  size_t off = 0;
  while (off < line.size()) {
    const ssize_t n = ::write(fd_.get(), line.data() + off, line.size() - off);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw std::runtime_error(fmt::format("{}: cannot append: {}", path_.string(), std::strerror(errno)));
    off += static_cast<size_t>(n);
  }
}

}  // namespace fpss
