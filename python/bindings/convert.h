// What the bindings share: JSON to and from Python objects, samples columns to a samples file, labels in messages.
#pragma once
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>
#include <pybind11/pybind11.h>

#include "calib/coefficients.h"

namespace fpss::pybind {

namespace py = ::pybind11;

// Through JSON text: Python's json module reads back every double nlohmann wrote (shortest
// round-trip text both ways), so numbers cross unchanged and key order is kept.
py::object to_python(const nlohmann::json& j);
py::object to_python(const nlohmann::ordered_json& j);
nlohmann::json from_python(const py::handle& o);

// A coefficient set from a Python dict (the coefficient file's content), checked as a file is;
// messages name `origin`.
CoefficientSet coefficients_from_python(const py::handle& o, const std::string& origin);

// Replaces every occurrence of `path` in `text` with `label` (a temporary samples file's path in a
// message becomes "DataFrame", the name the caller knows).
std::string relabel(std::string text, const std::string& path, const std::string& label);

void bind_samples(py::module_& m);
void bind_calib(py::module_& m);
void bind_catalogue(py::module_& m);
void bind_run_folder(py::module_& m);

}  // namespace fpss::pybind
