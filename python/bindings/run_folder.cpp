// A run folder for Python (open_run, Console): run.json through RunFile, events.jsonl through the
// typed event reader, points.jsonl through the recorder's journal reader, other JSON files through
// the one bounded JSON reader. No second parser: Python sees what these readers accept, or their
// InputError naming the file, the line and the key.
#include <pybind11/stl.h>

#include <string>

#include "base/json_file.h"
#include "procedures/events.h"
#include "procedures/recorder.h"
#include "convert.h"
#include "stand/catalogue/run_file.h"

namespace fpss::pybind {

namespace {

// A line's typed form written again: an engine event as the engine writes it, a note as its keys.
nlohmann::ordered_json line_json(const EventLine& l) {
  if (const auto* n = std::get_if<Note>(&l)) {
    nlohmann::ordered_json j{{"type", n->type}, {"utc", n->utc}};
    for (auto it = n->body.begin(); it != n->body.end(); ++it) j[it.key()] = it.value();
    return j;
  }
  return to_json(std::get<Event>(l));
}

nlohmann::ordered_json journal_json(const std::vector<JournalEntry>& entries) {
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  for (const auto& e : entries) {
    rows.push_back({{"point", e.point + 1},  // 1-based, as the file and the step column
                    {"step", e.step},
                    {"rows", e.rows},
                    {"bytes", e.bytes},
                    {"last_time_s", e.last_time_s},
                    {"utc", e.utc},
                    {"session", e.session},
                    {"attempts", e.attempts},
                    {"skipped", e.skipped.empty() ? nlohmann::ordered_json() : nlohmann::ordered_json(e.skipped)}});
  }
  return rows;
}

}  // namespace

void bind_run_folder(py::module_& m) {
  m.def(
      "read_run_file",
      [](const std::string& run_dir) {
        const RunFile r = read_run_file(run_dir);
        return py::make_tuple(to_python(to_json(r)), r.id_or(run_dir));
      },
      py::arg("run_dir"),
      "(run.json's content as RunFile writes it, the run id) of RUN_DIR/run.json, read by read_run_file "
      "(InputError naming the file and the key).");
  m.def(
      "run_file_from_json",
      [](const py::handle& o, const std::string& origin) { return to_python(to_json(run_file_from_json(from_python(o), origin))); },
      py::arg("content"), py::arg("origin"), "run.json's content checked and written again by RunFile.");
  m.def(
      "read_event_lines",
      [](const std::string& path) {
        nlohmann::ordered_json lines = nlohmann::ordered_json::array();
        read_event_lines(path, [&lines](EventLine&& l) { lines.push_back(line_json(l)); });
        return to_python(lines);
      },
      py::arg("path"),
      "events.jsonl's lines in their typed form (procedures/events.h read_event_lines), each as a dict.");
  m.def(
      "event_line",
      [](const py::handle& o, const std::string& origin) { return to_python(line_json(event_line_from_json(from_python(o), origin))); },
      py::arg("line"), py::arg("origin"), "One events.jsonl line (a dict) checked and typed by event_line_from_json.");
  m.def(
      "read_journal",
      [](const std::string& path) { return to_python(journal_json(RunRecorder::read_journal(path))); },
      py::arg("path"), "points.jsonl's entries (the recorder's journal reader: a torn last line left out).");
  m.def(
      "read_json_file",
      [](const std::string& path, const std::string& what) { return to_python(read_json_file(path, what)); },
      py::arg("path"), py::arg("what") = "JSON file",
      "A JSON file read by base/json_file.h's read_json_file (size, depth, duplicate keys).");
}

}  // namespace fpss::pybind
