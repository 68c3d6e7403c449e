// Catalogue(URL) for Python: the stand's catalogue (stand/catalogue, open_catalogue), read-only, either backend.
#include <pybind11/stl.h>

#include <memory>
#include <optional>
#include <string>

#include "convert.h"
#include "stand/catalogue/catalogue.h"

namespace fpss::pybind {

namespace {

nlohmann::json run_json(const RunRecord& r) {
  return {{"run_id", r.run_id},
          {"unit", r.unit},
          {"procedure", r.procedure},
          {"procedure_hash", r.procedure_hash},
          {"started_utc", r.started_utc},
          {"ended_utc", r.ended_utc ? nlohmann::json(*r.ended_utc) : nlohmann::json()},
          {"outcome", r.outcome_name()},
          {"stale", r.stale()},
          {"run_dir", r.run_dir},
          {"emulated", r.emulated},
          {"stand", r.stand},
          {"software_version", r.software_version},
          {"resumes", r.resumes},
          {"pid", r.pid},
          {"host", r.host},
          {"operator", r.operator_name}};
}

nlohmann::json calibration_json(const CalibrationRecord& c) {
  return {{"id", c.id},
          {"unit", c.unit},
          {"source", c.source},
          {"run_id", c.run_id ? nlohmann::json(*c.run_id) : nlohmann::json()},
          {"source_ref", c.source_ref},
          {"label", c.label},
          {"date_utc", c.date_utc},
          {"recorded_utc", c.recorded_utc},
          {"method", c.method},
          {"pitch", c.pitch ? c.pitch->to_json() : nlohmann::json()},
          {"yaw", c.yaw ? c.yaw->to_json() : nlohmann::json()},
          {"stand", c.stand},
          {"host", c.host},
          {"operator", c.operator_name},
          {"coefficients", c.coefficients}};
}

nlohmann::json acceptance_json(const AcceptanceRecord& a) {
  return {{"id", a.id},
          {"unit", a.unit},
          {"run_id", a.run_id ? nlohmann::json(*a.run_id) : nlohmann::json()},
          {"passed", a.passed},
          {"date_utc", a.date_utc},
          {"recorded_utc", a.recorded_utc},
          {"stand", a.stand},
          {"host", a.host},
          {"operator", a.operator_name},
          {"certificate", a.certificate}};
}

template <typename T, typename F>
py::list list_of(const std::vector<T>& records, F to_json) {
  py::list out;
  for (const auto& r : records) out.append(to_python(to_json(r)));
  return out;
}

}  // namespace

void bind_catalogue(py::module_& m) {
  py::class_<Catalogue, std::unique_ptr<Catalogue>>(m, "Catalogue")
      .def(py::init([](const std::string& url, bool writable) {
             return open_catalogue(url, writable ? Catalogue::Mode::read_write : Catalogue::Mode::read_only);
           }),
           py::arg("url"), py::arg("writable") = false)
      .def_property_readonly("location", &Catalogue::location)
      .def_property_readonly("backend", &Catalogue::backend)
      .def_property_readonly("schema_version", &Catalogue::schema_version)
      .def("units", &Catalogue::units)
      .def(
          "runs",
          [](const Catalogue& c, std::optional<std::string> unit, size_t limit) {
            RunFilter f;
            f.unit = std::move(unit);
            f.limit = limit;
            return list_of(c.list_runs(f), run_json);
          },
          py::arg("unit") = py::none(), py::arg("limit") = 0)
      .def(
          "run",
          [](const Catalogue& c, const std::string& run_id) -> py::object {
            const auto r = c.find_run(run_id);
            return r ? to_python(run_json(*r)) : py::none();
          },
          py::arg("run_id"))
      .def("history", [](const Catalogue& c, const std::string& serial) { return list_of(c.unit_history(serial), calibration_json); },
           py::arg("serial"))
      .def("run_calibrations",
           [](const Catalogue& c, const std::string& run_id) { return list_of(c.run_calibrations(run_id), calibration_json); },
           py::arg("run_id"))
      .def("acceptances",
           [](const Catalogue& c, const std::string& serial) { return list_of(c.unit_acceptances(serial), acceptance_json); },
           py::arg("serial"))
      .def("integrity_check", &Catalogue::integrity_check);
}

}  // namespace fpss::pybind
