// events.jsonl read back: each line's typed event (or the session's note), and a run replayed to an EventBus.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>

#include "base/errors.h"
#include "base/json_file.h"
#include "base/text_file.h"
#include "procedures/events.h"

namespace fpss {

namespace {

using json = nlohmann::json;
using ojson = nlohmann::ordered_json;

constexpr int64_t kMaxCount = int64_t{1} << 53;  // points, rows, sessions: far beyond any run

// The keys of one line, each read with its type and range; errors name the origin and the key.
class Keys {
 public:
  Keys(const json& j, const std::string& origin) : j_(j), origin_(origin) {}

  [[noreturn]] void bad(const std::string& key, const std::string& what) const {
    throw InputError(fmt::format("{}: key \"{}\": {}", origin_, key, what));
  }
  const json& at(const char* key) const {
    const auto it = j_.find(key);
    if (it == j_.end()) bad(key, "missing");
    return *it;
  }
  int64_t integer(const char* key, int64_t lo = 0, int64_t hi = kMaxCount) const { return integer_of(at(key), key, lo, hi); }
  int64_t integer_of(const json& v, const std::string& key, int64_t lo, int64_t hi) const {
    if (!v.is_number_integer()) bad(key, "expected a whole number");
    if (v.is_number_unsigned() && v.get<uint64_t>() > static_cast<uint64_t>(hi)) bad(key, fmt::format("above {}", hi));
    const int64_t x = v.get<int64_t>();
    if (x < lo || x > hi) bad(key, fmt::format("expected {}..{}, got {}", lo, hi, x));
    return x;
  }
  // A 1-based point number as the 0-based index.
  int64_t point(const char* key) const { return integer(key, 1) - 1; }
  double number_of(const json& v, const std::string& key) const {
    if (!v.is_number()) bad(key, "expected a number");
    const double x = v.get<double>();
    if (!std::isfinite(x)) bad(key, "expected a finite number");
    return x;
  }
  double number(const char* key) const { return number_of(at(key), key); }
  // A number, or null for "not known" (NaN).
  double number_or_null(const char* key) const {
    const json& v = at(key);
    return v.is_null() ? std::numeric_limits<double>::quiet_NaN() : number_of(v, key);
  }
  std::string text(const char* key) const {
    const json& v = at(key);
    if (!v.is_string()) bad(key, "expected a string");
    return v.get<std::string>();
  }
  bool boolean(const char* key) const {
    const json& v = at(key);
    if (!v.is_boolean()) bad(key, "expected true or false");
    return v.get<bool>();
  }

  EventPoint event_point() const {
    EventPoint p;
    p.index = point("point");
    p.step_index = static_cast<size_t>(integer("step"));
    const std::string kind = text("kind");
    if (kind == "dwell") p.kind = Action::Kind::dwell;
    else if (kind == "slew") p.kind = Action::Kind::slew;
    else bad("kind", fmt::format("expected dwell or slew, got \"{}\"", kind));
    const std::string phase = text("phase");
    const auto ph = parse_phase(phase);
    if (!ph) bad("phase", fmt::format("expected null, offset, slew or move, got \"{}\"", phase));
    p.phase = *ph;
    p.target_pitch_arcsec = number("target_pitch_arcsec");
    p.target_yaw_arcsec = number("target_yaw_arcsec");
    return p;
  }

 private:
  const json& j_;
  const std::string& origin_;
};

RunStarted run_started(const Keys& k) {
  RunStarted e;
  e.session = static_cast<int>(k.integer("session", 1, 1 << 30));
  e.first_point = k.point("first_point");
  e.points_total = static_cast<size_t>(k.integer("points_total"));
  e.estimated_s = k.number("estimated_s");
  const json& pts = k.at("points");
  if (!pts.is_array()) k.bad("points", "expected an array of [point, target_pitch_arcsec, target_yaw_arcsec]");
  e.points.reserve(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    const std::string key = fmt::format("points[{}]", i);
    const json& p = pts[i];
    if (!p.is_array() || p.size() != 3) k.bad(key, "expected [point, target_pitch_arcsec, target_yaw_arcsec]");
    e.points.push_back({k.integer_of(p[0], key, 1, kMaxCount) - 1, k.number_of(p[1], key), k.number_of(p[2], key)});
  }
  return e;
}

PointDone point_done(const Keys& k) {
  PointDone e;
  e.point = k.event_point();
  e.stats.rows = static_cast<size_t>(k.integer("rows"));
  e.stats.ref_pitch_arcsec = k.number("ref_pitch_arcsec");
  e.stats.ref_yaw_arcsec = k.number("ref_yaw_arcsec");
  e.stats.counts_alpha = k.number("counts_alpha");
  e.stats.counts_beta = k.number("counts_beta");
  e.stats.sd_counts_alpha = k.number("sd_counts_alpha");
  e.stats.sd_counts_beta = k.number("sd_counts_beta");
  e.attempts = static_cast<int>(k.integer("attempts", 0, 1 << 30));
  e.invalid_frames = static_cast<int>(k.integer("invalid_frames", 0, std::numeric_limits<int>::max()));
  e.temperature_c = k.number_or_null("temperature_c");
  e.valid = k.boolean("valid");
  return e;
}

StepStopped step_stopped(const Keys& k) {
  StepStopped e;
  e.step_index = static_cast<size_t>(k.integer("step"));
  e.axes = k.text("axes");
  if (e.axes != "pitch" && e.axes != "yaw" && e.axes != "both") k.bad("axes", "expected pitch, yaw or both");
  e.sigma_max_arcsec = k.number_or_null("sigma_max_arcsec");
  e.until_sigma_arcsec = k.number("until_sigma_arcsec");
  const json& sk = k.at("skipped_points");
  if (!sk.is_array()) k.bad("skipped_points", "expected an array of point numbers");
  for (size_t i = 0; i < sk.size(); ++i) e.skipped.push_back(k.integer_of(sk[i], fmt::format("skipped_points[{}]", i), 1, kMaxCount) - 1);
  if (k.integer("points_skipped") != static_cast<int64_t>(e.skipped.size())) {
    k.bad("points_skipped", fmt::format("{} points in skipped_points", e.skipped.size()));
  }
  const json& first = k.at("first_skipped_point");
  if (!(e.skipped.empty() ? first.is_null() : first.is_number_integer() && first.get<int64_t>() == e.skipped.front() + 1)) {
    k.bad("first_skipped_point", "not the first of skipped_points");
  }
  e.session = static_cast<int>(k.integer("session", 1, 1 << 30));
  return e;
}

Event event_of(const std::string& type, const Keys& k) {
  if (type == "run_started") return run_started(k);
  if (type == "point_started") return PointStarted{k.event_point(), static_cast<int>(k.integer("attempt", 1, 1 << 30)), {}};
  if (type == "samples") {
    Samples e;
    e.point = k.event_point();
    e.row_count = static_cast<size_t>(k.integer("rows"));
    e.attempt = static_cast<int>(k.integer("attempt", 1, 1 << 30));
    e.session = static_cast<int>(k.integer("session", 1, 1 << 30));
    return e;
  }
  if (type == "point_done") return point_done(k);
  if (type == "fit_updated") {
    FitUpdated e;
    e.points = k.integer("points");
    e.pairs = static_cast<size_t>(k.integer("pairs"));
    e.rms_pitch_arcsec = k.number_or_null("rms_pitch_arcsec");
    e.rms_yaw_arcsec = k.number_or_null("rms_yaw_arcsec");
    e.sigma_max_pitch_arcsec = k.number_or_null("sigma_max_pitch_arcsec");
    e.sigma_max_yaw_arcsec = k.number_or_null("sigma_max_yaw_arcsec");
    return e;
  }
  if (type == "step_stopped") return step_stopped(k);
  if (type == "paused") return Paused{k.point("next_point"), {}};
  if (type == "resumed") return Resumed{k.point("next_point"), {}};
  if (type == "warning" || type == "fault") {
    Fault e;
    e.level = type == "fault" ? Fault::Level::fault : Fault::Level::warning;
    e.point = k.at("point").is_null() ? -1 : k.point("point");
    e.message = k.text("message");
    return e;
  }
  if (type == "run_stopped") {
    RunStopped e;
    const std::string outcome = k.text("outcome");
    const auto o = parse_outcome(outcome);
    if (!o) k.bad("outcome", fmt::format("expected completed, failed or interrupted, got \"{}\"", outcome));
    e.outcome = *o;
    const std::string cause = k.text("cause");
    const auto c = parse_stop_cause(cause);
    if (!c) k.bad("cause", fmt::format("not a stop cause: \"{}\"", cause));
    e.cause = *c;
    e.reason = k.text("reason");
    e.points_done = k.integer("points_done");
    e.safe_state = k.boolean("safe_state");
    return e;
  }
  k.bad("type", fmt::format("unknown event type \"{}\"", type));
}

}  // namespace

const std::vector<std::string>& note_types() {
  static const std::vector<std::string> types{"point_residual", "prompt", "prompt_answered", "prompt_rejected"};
  return types;
}

EventLine event_line_from_json(const nlohmann::json& line, const std::string& origin) {
  if (!line.is_object()) throw InputError(fmt::format("{}: expected a JSON object", origin));
  const Keys k(line, origin);
  const std::string type = k.text("type");
  const std::string utc = k.text("utc");
  const auto& notes = note_types();
  if (std::find(notes.begin(), notes.end(), type) != notes.end()) {
    Note n{type, utc, ojson::object()};
    for (auto it = line.begin(); it != line.end(); ++it) {
      if (it.key() != "type" && it.key() != "utc") n.body[it.key()] = it.value();
    }
    return n;
  }
  Event e = event_of(type, k);
  std::visit([&](auto& x) { x.utc = utc; }, e);
  return e;
}

Event event_from_json(const nlohmann::json& line, const std::string& origin) {
  EventLine l = event_line_from_json(line, origin);
  if (auto* n = std::get_if<Note>(&l)) {
    throw InputError(fmt::format("{}: key \"type\": \"{}\" is a note of the run session, not an engine event", origin, n->type));
  }
  return std::get<Event>(std::move(l));
}

void read_event_lines(const std::filesystem::path& path, const std::function<void(EventLine&&)>& f) {
  check_input_file(path, "events file", kMaxTextFileBytes);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open the events file", path.string()));
  std::string buf, line;
  std::vector<char> chunk(1 << 16);
  size_t line_no = 0;
  uintmax_t total = 0;
  auto take = [&](const std::string& text) {
    ++line_no;
    const std::string origin = fmt::format("{}:{}", path.string(), line_no);
    f(event_line_from_json(parse_json_text(text, origin), origin));
  };
  while (in.read(chunk.data(), static_cast<std::streamsize>(chunk.size())) || in.gcount() > 0) {
    const size_t n = static_cast<size_t>(in.gcount());
    total += n;
    if (total > kMaxTextFileBytes) {
      throw InputError(fmt::format("{}: larger than {} bytes", path.string(), kMaxTextFileBytes));
    }
    size_t start = 0;
    for (size_t i = 0; i < n; ++i) {
      if (chunk[i] != '\n') continue;
      line.append(chunk.data() + start, i - start);
      if (line.size() > kMaxEventLineBytes) {
        throw InputError(fmt::format("{}:{}: a line longer than {} bytes", path.string(), line_no + 1, kMaxEventLineBytes));
      }
      take(line);
      line.clear();
      start = i + 1;
    }
    line.append(chunk.data() + start, n - start);
    if (line.size() > kMaxEventLineBytes) {
      throw InputError(fmt::format("{}:{}: a line longer than {} bytes", path.string(), line_no + 1, kMaxEventLineBytes));
    }
  }
  // `line` now holds a last line without its newline: a write cut short, left out.
}

ReplayCount replay_events(const std::filesystem::path& path, const EventBus& bus,
                          const std::function<void(const Note&)>& on_note) {
  ReplayCount c;
  read_event_lines(path, [&](EventLine&& l) {
    if (auto* e = std::get_if<Event>(&l)) {
      ++c.events;
      bus.publish(*e);
    } else {
      ++c.notes;
      if (on_note) on_note(std::get<Note>(l));
    }
  });
  return c;
}

}  // namespace fpss
