#include "stand/catalogue/run_file.h"

#include <fmt/format.h>

#include <cmath>

#include "base/errors.h"
#include "base/json_file.h"
#include "procedures/recorder.h"  // write_json_atomic

namespace fpss {

namespace {

using json = nlohmann::json;

// An object's keys, read with their types; errors name the origin and the key's path ("points.total").
class Obj {
 public:
  Obj(const json& j, std::string origin, std::string path) : j_(j), origin_(std::move(origin)), path_(std::move(path)) {
    if (!j_.is_object()) bad_at(path_, "expected an object");
  }
  [[noreturn]] void bad_at(const std::string& key, const std::string& what) const {
    throw InputError(fmt::format("{}: key \"{}\": {}", origin_, key, what));
  }
  std::string key(const char* k) const { return path_.empty() ? k : path_ + "." + k; }
  [[noreturn]] void bad(const char* k, const std::string& what) const { bad_at(key(k), what); }
  bool has(const char* k) const { return j_.contains(k); }
  const json& at(const char* k) const {
    if (!j_.contains(k)) bad(k, "missing");
    return j_.at(k);
  }
  Obj obj(const char* k) const { return Obj(at(k), origin_, key(k)); }
  std::string text(const char* k) const {
    const json& v = at(k);
    if (!v.is_string()) bad(k, "expected a string");
    return v.get<std::string>();
  }
  // Absent or null: nullopt.
  // An optional key: absent or null is nullopt, anything else must be what `get` reads.
  template <typename T>
  std::optional<T> optional(const char* k, T (Obj::*get)(const char*) const) const {
    if (!has(k) || j_.at(k).is_null()) return std::nullopt;
    return (this->*get)(k);
  }
  std::optional<std::string> opt_text(const char* k) const { return optional(k, &Obj::text); }
  int64_t integer(const char* k) const {
    const json& v = at(k);
    if (!v.is_number_integer() || (v.is_number_unsigned() && v.get<uint64_t>() > uint64_t{1} << 62)) {
      bad(k, "expected a whole number");
    }
    return v.get<int64_t>();
  }
  std::optional<int64_t> opt_integer(const char* k) const { return optional(k, &Obj::integer); }
  double number(const char* k) const {
    const json& v = at(k);
    if (!v.is_number()) bad(k, "expected a number");
    return v.get<double>();
  }
  std::optional<double> opt_number(const char* k) const { return optional(k, &Obj::number); }
  bool boolean(const char* k) const {
    const json& v = at(k);
    if (!v.is_boolean()) bad(k, "expected true or false");
    return v.get<bool>();
  }
  std::optional<bool> opt_boolean(const char* k) const {
    if (!has(k)) return std::nullopt;
    return boolean(k);
  }
  std::optional<json> opt_object(const char* k) const {
    if (!has(k)) return std::nullopt;
    if (!j_.at(k).is_object()) bad(k, "expected an object");
    return j_.at(k);
  }
  const json& array(const char* k) const {
    const json& v = at(k);
    if (!v.is_array()) bad(k, "expected an array");
    return v;
  }
  std::string origin() const { return origin_; }

 private:
  const json& j_;
  std::string origin_, path_;
};

void put(json& j, const char* k, const std::optional<std::string>& v) {
  if (v) j[k] = *v;
}
void put(json& j, const char* k, const std::optional<int64_t>& v) {
  if (v) j[k] = *v;
}
void put(json& j, const char* k, const std::optional<json>& v) {
  if (v) j[k] = *v;
}
json or_null(const std::optional<std::string>& v) { return v ? json(*v) : json(nullptr); }

RunFileSession session_of(const Obj& o) {
  RunFileSession s;
  s.session = o.integer("session");
  s.started_utc = o.opt_text("started_utc");
  s.ended_utc = o.opt_text("ended_utc");
  s.outcome = o.opt_text("outcome");
  s.reason = o.opt_text("reason");
  s.first_point = o.opt_integer("first_point");
  s.pid = o.opt_integer("pid");
  s.points_completed = o.opt_integer("points_completed");
  s.engine = o.opt_object("engine");
  s.sensor_stats = o.opt_object("sensor_stats");
  s.emulator = o.opt_object("emulator");
  return s;
}

json session_json(const RunFileSession& s) {
  json j = json::object();
  j["session"] = s.session;
  put(j, "started_utc", s.started_utc);
  put(j, "ended_utc", s.ended_utc);
  put(j, "outcome", s.outcome);
  put(j, "reason", s.reason);
  put(j, "first_point", s.first_point);
  put(j, "pid", s.pid);
  put(j, "points_completed", s.points_completed);
  put(j, "engine", s.engine);
  put(j, "sensor_stats", s.sensor_stats);
  put(j, "emulator", s.emulator);
  return j;
}

RunFileAdaptiveStop stop_of(const Obj& o) {
  RunFileAdaptiveStop a;
  a.step = o.integer("step");
  a.axes = o.text("axes");
  a.sigma_max_arcsec = o.opt_number("sigma_max_arcsec");
  a.until_sigma_arcsec = o.number("until_sigma_arcsec");
  a.points_skipped = o.integer("points_skipped");
  a.first_skipped_point = o.opt_integer("first_skipped_point");
  a.reason = o.text("reason");
  return a;
}

json stop_json(const RunFileAdaptiveStop& a) {
  return {{"step", a.step},
          {"axes", a.axes},
          {"sigma_max_arcsec", a.sigma_max_arcsec ? json(*a.sigma_max_arcsec) : json(nullptr)},
          {"until_sigma_arcsec", a.until_sigma_arcsec},
          {"points_skipped", a.points_skipped},
          {"first_skipped_point", a.first_skipped_point ? json(*a.first_skipped_point) : json(nullptr)},
          {"reason", a.reason}};
}

RunFileAcceptance acceptance_of(const Obj& o) {
  RunFileAcceptance a;
  a.file = o.opt_text("file");
  a.certificate = o.opt_text("certificate");
  a.verdict = o.text("verdict");
  if (a.verdict != "pass" && a.verdict != "fail" && a.verdict != "conditional") {
    o.bad("verdict", "expected pass, conditional or fail, got \"" + a.verdict + "\"");
  }
  if (o.has("failed")) {
    const json& f = o.array("failed");
    a.failed.emplace();
    for (const auto& x : f) {
      if (!x.is_string()) o.bad("failed", "expected an array of strings");
      a.failed->push_back(x.get<std::string>());
    }
  }
  if (o.has("limits")) {
    const Obj l = o.obj("limits");
    a.limits = RunFileAcceptance::Limits{l.text("file"), l.text("sha256")};
  }
  return a;
}

json acceptance_json(const RunFileAcceptance& a) {
  json j = json::object();
  put(j, "file", a.file);
  put(j, "certificate", a.certificate);
  j["verdict"] = a.verdict;
  if (a.failed) j["failed"] = *a.failed;
  if (a.limits) j["limits"] = {{"file", a.limits->file}, {"sha256", a.limits->sha256}};
  return j;
}

RunFileUnit unit_of(const Obj& o) {
  RunFileUnit u;
  u.serial = o.text("serial");
  u.sensor_id = o.opt_text("sensor_id");
  u.endpoint = o.opt_text("endpoint");
  u.outcome = o.text("outcome");
  if (u.outcome != "running" && u.outcome != "completed" && u.outcome != "lost" && u.outcome != "failed" &&
      u.outcome != "interrupted") {
    o.bad("outcome", "expected running, completed, lost, failed or interrupted, got \"" + u.outcome + "\"");
  }
  u.loss_cause = o.opt_text("loss_cause");
  if (u.loss_cause && !parse_loss_cause(*u.loss_cause)) o.bad("loss_cause", "unknown cause \"" + *u.loss_cause + "\"");
  u.reason = o.opt_text("reason");
  u.lost_at_point = o.opt_integer("lost_at_point");
  u.samples = o.opt_text("samples");
  u.calibration = o.opt_text("calibration");
  u.acceptance = o.opt_text("acceptance");
  u.certificate = o.opt_text("certificate");
  u.verdict = o.opt_text("verdict");
  if (o.has("relative") && !o.at("relative").is_null()) {
    const Obj r = o.obj("relative");
    u.relative = RunFileRelative{r.text("to"),
                                 r.number("boresight_pitch_arcsec"), r.number("boresight_pitch_sigma_arcsec"),
                                 r.number("boresight_yaw_arcsec"), r.number("boresight_yaw_sigma_arcsec"),
                                 r.number("roll_arcsec"), r.number("roll_sigma_arcsec")};
  }
  return u;
}

}  // namespace

json to_json(const RunFileUnit& u) {
  json j = json::object();
  j["serial"] = u.serial;
  put(j, "sensor_id", u.sensor_id);
  put(j, "endpoint", u.endpoint);
  j["outcome"] = u.outcome;
  put(j, "loss_cause", u.loss_cause);
  put(j, "reason", u.reason);
  put(j, "lost_at_point", u.lost_at_point);
  put(j, "samples", u.samples);
  put(j, "calibration", u.calibration);
  put(j, "acceptance", u.acceptance);
  put(j, "certificate", u.certificate);
  put(j, "verdict", u.verdict);
  if (u.relative) {
    const RunFileRelative& r = *u.relative;
    j["relative"] = {{"to", r.to},
                     {"boresight_pitch_arcsec", r.boresight_pitch_arcsec},
                     {"boresight_pitch_sigma_arcsec", r.boresight_pitch_sigma_arcsec},
                     {"boresight_yaw_arcsec", r.boresight_yaw_arcsec},
                     {"boresight_yaw_sigma_arcsec", r.boresight_yaw_sigma_arcsec},
                     {"roll_arcsec", r.roll_arcsec},
                     {"roll_sigma_arcsec", r.roll_sigma_arcsec}};
  }
  return j;
}

namespace {

const char* const kKnown[] = {"format",         "run_id",  "software", "procedure",  "stand",     "unit",
                              "sensor_id",      "emulated", "emulator", "started_utc", "ended_utc", "outcome",
                              "reason",         "stop_cause", "points", "adaptive_stops", "safe_state", "operator",
                              "signed_off_utc", "sessions", "files",   "acceptance", "reference", "units"};

void read_top(RunFile& r, const Obj& o) {
  r.format = o.opt_text("format");
  r.run_id = o.opt_text("run_id");
  if (o.has("software")) {
    const Obj s = o.obj("software");
    r.software = RunFile::Software{s.text("name"), s.text("version")};
  }
  const Obj p = o.obj("procedure");
  r.procedure.name = p.text("name");
  r.procedure.sha256 = p.text("sha256");
  r.procedure.text = p.text("text");
  r.procedure.file = p.opt_text("file");
  if (o.has("stand")) {
    const Obj s = o.obj("stand");
    r.stand = RunFile::Stand{s.opt_text("file"), s.opt_text("text"), s.opt_object("settings").value_or(json())};
  }
  r.unit = o.text("unit");
  r.sensor_id = o.opt_text("sensor_id");
  r.emulated = o.boolean("emulated");
  r.emulator = o.opt_object("emulator");
  r.started_utc = o.text("started_utc");
  r.ended_utc = o.opt_text("ended_utc");
  r.outcome = o.text("outcome");
  if (r.outcome != "running" && !parse_outcome(r.outcome)) {
    o.bad("outcome", "expected running, completed, failed or interrupted, got \"" + r.outcome + "\"");
  }
  r.reason = o.opt_text("reason");
  if (const auto c = o.opt_text("stop_cause")) {
    r.stop_cause = parse_stop_cause(*c);
    if (!r.stop_cause) o.bad("stop_cause", "not a stop cause: \"" + *c + "\"");
  }
}

}  // namespace

RunFileAdaptiveStop RunFileAdaptiveStop::of(const StepStopped& s) {
  RunFileAdaptiveStop a;
  a.step = static_cast<int64_t>(s.step_index);
  a.axes = s.axes;
  if (std::isfinite(s.sigma_max_arcsec)) a.sigma_max_arcsec = s.sigma_max_arcsec;
  a.until_sigma_arcsec = s.until_sigma_arcsec;
  a.points_skipped = static_cast<int64_t>(s.skipped.size());
  if (!s.skipped.empty()) a.first_skipped_point = s.skipped.front() + 1;
  a.reason = s.reason();
  return a;
}

std::optional<std::string> acceptance_verdict(const RunFile& run) {
  if (run.acceptance) return run.acceptance->verdict;
  if (!run.units) return std::nullopt;
  bool any = false, conditional = false, fail = false;
  for (const RunFileUnit& u : *run.units) {
    if (u.outcome == "lost") fail = any = true;
    if (!u.verdict) continue;
    any = true;
    fail = fail || *u.verdict == "fail";
    conditional = conditional || *u.verdict == "conditional";
  }
  if (!any) return std::nullopt;
  return fail ? "fail" : conditional ? "conditional" : "pass";
}

std::string RunFile::id_or(const std::filesystem::path& run_dir) const {
  return run_id && !run_id->empty() ? *run_id : run_dir.filename().string();
}

RunFile run_file_from_json(const nlohmann::json& j, const std::string& origin) {
  if (!j.is_object()) throw InputError(fmt::format("{}: expected a JSON object", origin));
  const Obj o(j, origin, "");
  RunFile r;
  read_top(r, o);
  const Obj pts = o.obj("points");
  r.points.total = pts.integer("total");
  r.points.completed = pts.integer("completed");
  r.points.skipped = pts.opt_integer("skipped");
  if (o.has("adaptive_stops")) {
    r.adaptive_stops.emplace();
    const json& a = o.array("adaptive_stops");
    for (size_t i = 0; i < a.size(); ++i) r.adaptive_stops->push_back(stop_of(Obj(a[i], origin, fmt::format("adaptive_stops[{}]", i))));
  }
  r.safe_state = o.opt_boolean("safe_state");
  r.operator_name = o.opt_text("operator");
  r.signed_off_utc = o.opt_text("signed_off_utc");
  const json& ss = o.array("sessions");
  for (size_t i = 0; i < ss.size(); ++i) r.sessions.push_back(session_of(Obj(ss[i], origin, fmt::format("sessions[{}]", i))));
  const Obj f = o.obj("files");
  r.files = {f.opt_text("samples"),     f.opt_text("journal"),     f.opt_text("events"),
             f.opt_text("event_stream"), f.opt_text("calibration"), f.opt_text("gap")};
  if (o.has("acceptance")) r.acceptance = acceptance_of(o.obj("acceptance"));
  if (o.has("units")) {
    const json& a = o.array("units");
    if (a.size() > 64) o.bad("units", "more than 64 units");
    r.units.emplace();
    for (size_t i = 0; i < a.size(); ++i) r.units->push_back(unit_of(Obj(a[i], o.origin(), fmt::format("units[{}]", i))));
  }
  if (o.has("reference")) {
    const Obj ref = o.obj("reference");
    r.reference = RunFileReference{ref.text("file"), ref.text("sha256"), ref.text("certificate"), ref.text("date"),
                                   ref.text("lab")};
  }
  for (auto it = j.begin(); it != j.end(); ++it) {
    bool known = false;
    for (const char* k : kKnown) known |= it.key() == k;
    if (!known) r.extra[it.key()] = it.value();
  }
  return r;
}

nlohmann::json to_json(const RunFile& r) {
  json j = r.extra.is_object() ? r.extra : json::object();
  put(j, "format", r.format);
  put(j, "run_id", r.run_id);
  if (r.software) j["software"] = {{"name", r.software->name}, {"version", r.software->version}};
  j["procedure"] = {{"name", r.procedure.name}, {"sha256", r.procedure.sha256}, {"text", r.procedure.text}};
  put(j["procedure"], "file", r.procedure.file);
  if (r.stand) j["stand"] = {{"file", or_null(r.stand->file)}, {"text", or_null(r.stand->text)}, {"settings", r.stand->settings}};
  j["unit"] = r.unit;
  put(j, "sensor_id", r.sensor_id);
  j["emulated"] = r.emulated;
  put(j, "emulator", r.emulator);
  j["started_utc"] = r.started_utc;
  put(j, "ended_utc", r.ended_utc);
  j["outcome"] = r.outcome;
  put(j, "reason", r.reason);
  if (r.stop_cause) j["stop_cause"] = to_string(*r.stop_cause);
  j["points"] = {{"total", r.points.total}, {"completed", r.points.completed}};
  put(j["points"], "skipped", r.points.skipped);
  if (r.adaptive_stops) {
    j["adaptive_stops"] = json::array();
    for (const auto& a : *r.adaptive_stops) j["adaptive_stops"].push_back(stop_json(a));
  }
  if (r.safe_state) j["safe_state"] = *r.safe_state;
  put(j, "operator", r.operator_name);
  put(j, "signed_off_utc", r.signed_off_utc);
  j["sessions"] = json::array();
  for (const auto& s : r.sessions) j["sessions"].push_back(session_json(s));
  json files = json::object();
  put(files, "samples", r.files.samples);
  put(files, "journal", r.files.journal);
  put(files, "events", r.files.events);
  put(files, "event_stream", r.files.event_stream);
  put(files, "calibration", r.files.calibration);
  put(files, "gap", r.files.gap);
  j["files"] = files;
  if (r.acceptance) j["acceptance"] = acceptance_json(*r.acceptance);
  if (r.units) {
    j["units"] = json::array();
    for (const auto& u : *r.units) j["units"].push_back(to_json(u));
  }
  if (r.reference) {
    j["reference"] = {{"file", r.reference->file}, {"sha256", r.reference->sha256}, {"certificate", r.reference->certificate},
                      {"date", r.reference->date}, {"lab", r.reference->lab}};
  }
  return j;
}

RunFile read_run_file(const std::filesystem::path& run_dir) {
  const auto path = run_dir / "run.json";
  return run_file_from_json(read_json_file(path, "run file"), path.string());
}

void write_run_file(const std::filesystem::path& run_dir, const RunFile& r) {
  write_json_atomic(run_dir / "run.json", to_json(r));
}

}  // namespace fpss
