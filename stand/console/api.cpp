// The console's JSON API (docs/console.md): status, stand, procedures, jobs, runs, control, prompts, units, compare.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <memory>
#include <optional>
#include <variant>
#include <vector>

#include <fmt/format.h>
#include <httplib.h>

#include "base/errors.h"
#include "base/json_file.h"
#include "base/text_file.h"
#include "calib/coefficients.h"
#include "calib/compare.h"
#include "procedures/events.h"
#include "stand/catalogue/catalogue.h"
#include "stand/console/fleet.h"
#include "stand/console/run_files.h"
#include "stand/console/server.h"
#include "stand/session/control_channel.h"

namespace fpss::console {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

void reply(httplib::Response& res, const json& j, int status = 200) {
  res.status = status;
  res.set_content(j.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}
void fail(httplib::Response& res, int status, const std::string& why) { reply(res, {{"error", why}}, status); }

// A request body as a JSON object (bounded by the server's payload limit and nlohmann's parser).
std::optional<json> body_object(const httplib::Request& req, httplib::Response& res) {
  try {
    json j = parse_json_text(req.body, "request body", 4);  // the project's one JSON reader: depth, duplicates
    if (j.is_object()) return j;
    fail(res, 400, "the body must be a JSON object");
  } catch (const std::exception& e) {
    fail(res, 400, e.what());
  }
  return std::nullopt;
}

std::string str(const json& j, const char* key) {
  return j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : std::string();
}

// What the stand page shows, from the newest lines of the live (or latest) run's events.jsonl.
json stand_state(const Context& c) {
  json s{{"mode", c.opt.emulate ? "emulated" : "stand"},
         {"stand_file", c.opt.stand_file.string()},
         {"emulator_args", c.opt.emulator_args},
         {"connected", false},
         {"state", "idle"}};
  const auto live = live_runs(*c.catalogue);
  if (live.empty()) return s;
  const RunRef& r = live.front();
  s["run_id"] = r.run_id;
  s["connected"] = true;
  s["state"] = "running";
  std::error_code ec;
  const uint64_t size = fs::file_size(r.dir / "events.jsonl", ec);
  if (ec) return s;
  const EventChunk ch = read_events(r.dir, size > 65536 ? size - 65536 : 0, 65536);
  for (const auto& line : ch.lines) {
    std::optional<EventLine> l;
    try {
      const std::string origin = (r.dir / "events.jsonl").string();
      l = event_line_from_json(parse_json_text(line, origin), origin);
    } catch (const InputError&) {
      continue;  // the first line of a chunk cut mid-way, or a line this version does not know
    }
    if (const auto* n = std::get_if<Note>(&*l)) {
      if (n->type == "prompt") s["state"] = "waiting for the operator";
      continue;
    }
    const Event& e = std::get<Event>(*l);
    if (const auto* p = std::get_if<PointDone>(&e)) {
      s["gimbal"] = {{"pitch_arcsec", p->stats.ref_pitch_arcsec}, {"yaw_arcsec", p->stats.ref_yaw_arcsec},
                     {"point", p->point.index + 1}};
      s["sensor"] = {{"rows", p->stats.rows}, {"invalid_frames", p->invalid_frames}, {"attempts", p->attempts}};
      s["temperature_c"] = std::isfinite(p->temperature_c) ? json(p->temperature_c) : json(nullptr);
      if (s["state"] != "faulted") s["state"] = "running";
    } else if (std::holds_alternative<Paused>(e)) {
      s["state"] = "paused";
    } else if (std::holds_alternative<Resumed>(e)) {
      s["state"] = "running";
    } else if (const auto* f = std::get_if<Fault>(&e)) {
      if (f->level == Fault::Level::fault) {
        s["state"] = "faulted";
        s["last_fault"] = f->message;
      } else {
        s["last_warning"] = f->message;
      }
    }
  }
  return s;
}

json procedures(const Context& c) {
  json out = json::array();
  std::error_code ec;
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(c.opt.procedures_dir, ec)) {
    const std::string n = e.path().filename().string();
    if (e.path().extension() != ".yaml" || !safe_name(n) || !e.is_regular_file()) continue;
    try {
      const std::string text = read_text_file(e.path(), "procedure", 1024 * 1024);
      if (text.find("steps:") != std::string::npos) names.push_back(n);
    } catch (const std::exception&) {
    }
  }
  std::sort(names.begin(), names.end());
  for (const auto& n : names) out.push_back(n);
  return out;
}

Job job_of(const json& b) {
  Job j;
  j.kind = b.contains("kind") ? str(b, "kind") : "run";
  j.procedure = str(b, "procedure");
  j.model = str(b, "model");
  j.unit = str(b, "unit");
  j.operator_name = str(b, "operator");
  return j;
}

void add_job_routes(httplib::Server& s, Context& c) {
  s.Get("/api/jobs", [&c](const httplib::Request&, httplib::Response& res) {
    json a = json::array();
    for (const auto& j : c.jobs->list()) a.push_back(j.to_json());
    reply(res, a);
  });
  s.Get(R"(/api/jobs/(\d{1,12}))", [&c](const httplib::Request& req, httplib::Response& res) {
    const auto j = c.jobs->find(std::stoll(req.matches[1]));
    j ? reply(res, j->to_json()) : fail(res, 404, "no such job");
  });
  s.Post("/api/jobs", [&c](const httplib::Request& req, httplib::Response& res) {
    const auto b = body_object(req, res);
    if (!b) return;
    try {
      reply(res, c.jobs->add(job_of(*b)).to_json(), 201);
    } catch (const std::invalid_argument& e) {
      fail(res, 400, e.what());
    }
  });
  // A plan's jobs at once, every one or none: {"jobs": [job, ...]} (what `msa plan` writes per stand).
  s.Post("/api/jobs/batch", [&c](const httplib::Request& req, httplib::Response& res) {
    const auto b = body_object(req, res);
    if (!b) return;
    if (!b->contains("jobs") || !(*b)["jobs"].is_array() || (*b)["jobs"].empty()) {
      return fail(res, 400, "jobs: a non-empty list of jobs");
    }
    std::vector<Job> jobs;
    for (size_t i = 0; i < (*b)["jobs"].size(); ++i) {
      const json& j = (*b)["jobs"][i];
      if (!j.is_object()) return fail(res, 400, fmt::format("jobs[{}]: expected an object", i));
      jobs.push_back(job_of(j));
    }
    try {
      json a = json::array();
      for (const Job& j : c.jobs->add_all(std::move(jobs))) a.push_back(j.to_json());
      reply(res, {{"jobs", a}}, 201);
    } catch (const std::invalid_argument& e) {
      fail(res, 400, e.what());
    }
  });
  s.Delete(R"(/api/jobs/(\d{1,12}))", [&c](const httplib::Request& req, httplib::Response& res) {
    c.jobs->remove(std::stoll(req.matches[1])) ? reply(res, {{"removed", true}}) : fail(res, 404, "no queued job with that id");
  });
  s.Post(R"(/api/jobs/(\d{1,12})/move)", [&c](const httplib::Request& req, httplib::Response& res) {
    const auto b = body_object(req, res);
    if (!b) return;
    if (!b->contains("to") || !(*b)["to"].is_number_unsigned()) return fail(res, 400, "to: the new 0-based place");
    c.jobs->move(std::stoll(req.matches[1]), (*b)["to"].get<size_t>()) ? reply(res, {{"moved", true}})
                                                                       : fail(res, 404, "no queued job with that id");
  });
}

// A change to RUN_DIR/control.json, which the run polls: the body a JSON object, the run named in
// the path running. Under the control lock, `change` applies the body to the request and returns
// the fields its reply adds, or nothing when it has refused the request (and answered it).
using ControlChange = std::function<std::optional<json>(const json& body, ControlRequest& cr)>;

void change_control(Context& c, const httplib::Request& req, httplib::Response& res, const ControlChange& change) {
  const auto b = body_object(req, res);
  if (!b) return;
  const auto run = find_run(*c.catalogue, req.matches[1]);
  if (!run) return fail(res, 404, "no such run");
  if (!run->live) return fail(res, 409, "the run is not running");
  std::lock_guard<std::mutex> g(c.control_mutex);
  ControlRequest cr = read_control(run->dir).value_or(ControlRequest{});
  std::optional<json> fields = change(*b, cr);
  if (!fields) return;
  write_control(run->dir, cr);
  (*fields)["run_id"] = run->run_id;
  (*fields)["accepted"] = true;
  reply(res, *fields);
}

// Pause, resume, abort and prompt answers.
void add_control_routes(httplib::Server& s, Context& c) {
  s.Post(R"(/api/runs/([A-Za-z0-9._-]+)/control)", [&c](const httplib::Request& req, httplib::Response& res) {
    change_control(c, req, res, [&res](const json& b, ControlRequest& cr) -> std::optional<json> {
      const std::string action = str(b, "action");
      if (action == "pause") cr.pause = true;
      else if (action == "resume") cr.pause = false;
      else if (action == "abort") cr.abort = true;
      else {
        fail(res, 400, "action: pause, resume or abort");
        return std::nullopt;
      }
      return json{{"action", action}};
    });
  });
  s.Post(R"(/api/runs/([A-Za-z0-9._-]+)/answer)", [&c](const httplib::Request& req, httplib::Response& res) {
    change_control(c, req, res, [&res](const json& b, ControlRequest& cr) -> std::optional<json> {
      const std::string id = str(b, "id"), value = str(b, "value");
      if (!safe_name(id) || value.size() > 200) {
        fail(res, 400, "id: a prompt id; value: at most 200 characters");
        return std::nullopt;
      }
      if (cr.answers.size() >= 50) {
        fail(res, 400, "too many answers");
        return std::nullopt;
      }
      cr.answers[id] = value;
      return json{{"id", id}};
    });
  });
}

// A file of a run or investigation folder (already checked by run_file), streamed in 64 KiB pieces:
// a samples.csv of millions of rows is never held whole.
void serve_file(httplib::Response& res, const std::optional<fs::path>& file) {
  if (!file) return fail(res, 404, "no such file");
  auto in = std::make_shared<std::ifstream>(*file, std::ios::binary);
  std::error_code ec;
  const auto size = fs::file_size(*file, ec);
  if (!*in || ec) return fail(res, 404, "cannot read the file");
  const std::string ext = file->extension().string();
  const std::string type = ext == ".html" ? "text/html; charset=utf-8"
                           : ext == ".json" || ext == ".jsonl" ? "application/json"
                           : ext == ".svg" ? "image/svg+xml"
                           : ext == ".png" ? "image/png"
                           : ext == ".csv" ? "text/csv" : "text/plain; charset=utf-8";
  if (ext == ".csv") res.set_header("Content-Disposition", "attachment; filename=\"" + file->filename().string() + "\"");
  res.set_content_provider(static_cast<size_t>(size), type, [in](size_t offset, size_t length, httplib::DataSink& sink) {
    std::vector<char> buf(std::min<size_t>(length, 64 * 1024));
    in->seekg(static_cast<std::streamoff>(offset));
    in->read(buf.data(), static_cast<std::streamsize>(buf.size()));
    const auto n = in->gcount();
    return n > 0 && sink.write(buf.data(), static_cast<size_t>(n));
  });
}

void add_run_routes(httplib::Server& s, Context& c) {
  s.Get("/api/runs", [&c](const httplib::Request& req, httplib::Response& res) {
    size_t limit = 200;
    try {
      if (req.has_param("limit")) limit = std::min<size_t>(std::stoul(req.get_param_value("limit")), 5000);
    } catch (const std::exception&) {
      return fail(res, 400, "limit: a number");
    }
    reply(res, runs_json(*c.catalogue, req.get_param_value("unit"), req.get_param_value("outcome"),
                         req.get_param_value("from"), req.get_param_value("to"), limit));
  });
  s.Get(R"(/api/runs/([A-Za-z0-9._-]+))", [&c](const httplib::Request& req, httplib::Response& res) {
    const auto run = find_run(*c.catalogue, req.matches[1]);
    run ? reply(res, run_json(*run)) : fail(res, 404, "no such run");
  });
  s.Get(R"(/api/runs/([A-Za-z0-9._-]+)/events)", [&c](const httplib::Request& req, httplib::Response& res) {
    const auto run = find_run(*c.catalogue, req.matches[1]);
    if (!run) return fail(res, 404, "no such run");
    uint64_t from = 0;
    try {
      if (req.has_param("from")) from = std::stoull(req.get_param_value("from"));
    } catch (const std::exception&) {
      return fail(res, 400, "from: a byte offset");
    }
    const EventChunk ch = read_events(run->dir, from);
    json lines = json::array();
    for (const auto& l : ch.lines) lines.push_back(json::parse(l, nullptr, false));
    reply(res, {{"events", lines}, {"next", ch.next}, {"live", run->live}});
  });
  s.Get(R"(/runs/([A-Za-z0-9._-]+)/(.+))", [&c](const httplib::Request& req, httplib::Response& res) {
    const auto run = find_run(*c.catalogue, req.matches[1]);
    serve_file(res, run ? run_file(run->dir, req.matches[2]) : std::nullopt);
  });
  // Investigations (investigate's folders in the runs folder): their list and their files.
  s.Get("/api/investigations", [&c](const httplib::Request&, httplib::Response& res) {
    reply(res, investigations_json(c.opt.runs_dir));
  });
  s.Get(R"(/investigations/([A-Za-z0-9._-]+)/(.+))", [&c](const httplib::Request& req, httplib::Response& res) {
    const auto dir = investigation_dir(c.opt.runs_dir, req.matches[1]);
    serve_file(res, dir ? run_file(*dir, req.matches[2]) : std::nullopt);
  });
}

void add_unit_routes(httplib::Server& s, Context& c) {
  s.Get(R"(/api/units/([A-Za-z0-9._-]+)/history)", [&c](const httplib::Request& req, httplib::Response& res) {
    json cals = json::array(), accs = json::array();
    try {
      const auto catp = c.catalogue->acquire();
      if (!catp) throw std::runtime_error("no catalogue yet");
      Catalogue& cat = *catp;
      for (const auto& h : cat.unit_history(req.matches[1])) {
        json j{{"id", h.id}, {"date_utc", h.date_utc}, {"source", h.source}, {"label", h.label}, {"method", h.method},
               {"run_id", h.run_id ? json(*h.run_id) : json()}};
        if (h.pitch) j["pitch"] = h.pitch->to_json();
        if (h.yaw) j["yaw"] = h.yaw->to_json();
        cals.push_back(j);
      }
      for (const auto& a : cat.unit_acceptances(req.matches[1])) {
        accs.push_back({{"id", a.id}, {"date_utc", a.date_utc}, {"passed", a.passed},
                        {"run_id", a.run_id ? json(*a.run_id) : json()},
                        {"operator", a.certificate.value("operator", "")}});
      }
    } catch (const std::exception& e) {
      return fail(res, 404, e.what());
    }
    reply(res, {{"unit", std::string(req.matches[1])}, {"calibrations", cals}, {"acceptances", accs}});
  });
  s.Get("/api/fleet", [&c](const httplib::Request&, httplib::Response& res) {
    try {
      reply(res, fleet_json(*c.catalogue));
    } catch (const std::exception& e) {
      fail(res, 503, e.what());
    }
  });
  s.Get("/api/units", [&c](const httplib::Request&, httplib::Response& res) {
    try {
      const auto catp = c.catalogue->acquire();
      if (!catp) throw std::runtime_error("no catalogue yet");
      Catalogue& cat = *catp;
      reply(res, cat.units());
    } catch (const std::exception&) {
      reply(res, json::array());
    }
  });
  // B - A over the field (the paper's Figures 1-2), both from the catalogue.
  s.Get("/api/compare", [&c](const httplib::Request& req, httplib::Response& res) {
    try {
      const auto catp = c.catalogue->acquire();
      if (!catp) throw std::runtime_error("no catalogue yet");
      Catalogue& cat = *catp;
      const auto a = cat.find_calibration(std::stoll(req.get_param_value("a")));
      const auto b = cat.find_calibration(std::stoll(req.get_param_value("b")));
      if (!a || !b) return fail(res, 404, "no such calibration");
      const CalibrationComparison cc = compare_calibrations(parse_coefficients(a->coefficients, "calibration a"),
                                                            parse_coefficients(b->coefficients, "calibration b"));
      json out = json::parse(cc.detail_json().dump());
      for (const auto* ax : {&cc.alpha, &cc.beta}) {
        out[ax->axis]["angle_a_arcsec"] = ax->angle_a_arcsec;
        out[ax->axis]["diff_arcsec"] = ax->diff_arcsec;
      }
      reply(res, out);
    } catch (const std::exception& e) {
      fail(res, 400, e.what());
    }
  });
}

}  // namespace

void add_api(httplib::Server& s, Context& c) {
  s.Get("/api/status", [&c](const httplib::Request&, httplib::Response& res) {
    json live = json::array();
    for (const auto& r : live_runs(*c.catalogue)) live.push_back(r.run_id);
    json jobs = json::array();
    for (const auto& j : c.jobs->list()) jobs.push_back(j.to_json());
    reply(res, {{"live_runs", live}, {"jobs", jobs}, {"emulate", c.opt.emulate},
                {"reads_need_token", !is_loopback(c.opt.host)}, {"version", FPSS_VERSION}});
  });
  s.Get("/api/stand", [&c](const httplib::Request&, httplib::Response& res) { reply(res, stand_state(c)); });
  s.Get("/api/procedures", [&c](const httplib::Request&, httplib::Response& res) { reply(res, procedures(c)); });
  add_job_routes(s, c);
  add_control_routes(s, c);
  add_run_routes(s, c);
  add_unit_routes(s, c);
}

}  // namespace fpss::console
