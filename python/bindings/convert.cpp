// JSON to and from Python objects; the samples table built from a DataFrame's columns and written as samples.csv.
#include "convert.h"

#include <fmt/format.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "base/errors.h"
#include "calib/samples.h"

namespace fpss::pybind {

namespace {

py::object json_loads(const std::string& text) {
  return py::module_::import("json").attr("loads")(py::str(text));
}

// The required columns as arrays, the extras as text (a number in the writer's shortest form).
SampleTable table_from_columns(const py::dict& cols, const std::string& label) {
  auto num = [&](const char* name) {
    if (!cols.contains(name)) throw InputError(fmt::format("{}: no column '{}'", label, name));
    return py::array_t<double, py::array::c_style | py::array::forcecast>(cols[name]);
  };
  const auto t = num("time_s"), rp = num("ref_pitch_arcsec"), ry = num("ref_yaw_arcsec");
  const auto ca = num("counts_alpha"), cb = num("counts_beta");
  if (!cols.contains("step")) throw InputError(fmt::format("{}: no column 'step'", label));
  if (!cols.contains("phase")) throw InputError(fmt::format("{}: no column 'phase'", label));
  const auto step = py::array_t<int64_t, py::array::c_style | py::array::forcecast>(cols["step"]);
  const auto phase = cols["phase"].cast<std::vector<std::string>>();
  const size_t n = static_cast<size_t>(t.size());
  for (const auto* a : {&rp, &ry, &ca, &cb}) {
    if (static_cast<size_t>(a->size()) != n) throw InputError(fmt::format("{}: columns of different lengths", label));
  }
  if (static_cast<size_t>(step.size()) != n || phase.size() != n) {
    throw InputError(fmt::format("{}: columns of different lengths", label));
  }
  SampleTable table;
  std::vector<std::vector<std::string>> extras;
  for (const auto& [key, value] : cols) {
    const std::string name = key.cast<std::string>();
    bool required = false;
    for (const char* r : SampleTable::kRequired) required = required || name == r;
    if (required) continue;
    table.add_extra_column(name);
    const py::array arr = py::array::ensure(value);
    std::vector<std::string> text;
    if (arr && arr.dtype().kind() == 'f') {
      const auto d = py::array_t<double, py::array::c_style | py::array::forcecast>(arr);
      for (py::ssize_t i = 0; i < d.size(); ++i) text.push_back(std::isnan(d.data()[i]) ? "" : format_number(d.data()[i]));
    } else if (arr && (arr.dtype().kind() == 'i' || arr.dtype().kind() == 'u' || arr.dtype().kind() == 'b')) {
      const auto d = py::array_t<int64_t, py::array::c_style | py::array::forcecast>(arr);
      for (py::ssize_t i = 0; i < d.size(); ++i) text.push_back(std::to_string(d.data()[i]));
    } else {
      for (const auto& v : value) text.push_back(v.is_none() ? "" : py::str(v).cast<std::string>());
    }
    if (text.size() != n) throw InputError(fmt::format("{}: column '{}' of a different length", label, name));
    extras.push_back(std::move(text));
  }
  table.reserve(n);
  std::vector<std::string> row(extras.size());
  for (size_t i = 0; i < n; ++i) {
    const auto p = parse_phase(phase[i]);
    if (!p) {
      throw InputError(fmt::format("{}: row {}: phase '{}': expected null, offset, slew or move", label, i, phase[i]));
    }
    const Sample s{t.data()[i], *p, step.data()[i], rp.data()[i], ry.data()[i], ca.data()[i], cb.data()[i]};
    for (size_t k = 0; k < extras.size(); ++k) row[k] = extras[k][i];
    table.push_back(s, row);
  }
  table.origin = label;
  return table;
}

}  // namespace

py::object to_python(const nlohmann::json& j) { return json_loads(j.dump()); }
py::object to_python(const nlohmann::ordered_json& j) { return json_loads(j.dump()); }

nlohmann::json from_python(const py::handle& o) {
  const std::string text = py::module_::import("json").attr("dumps")(o, py::arg("allow_nan") = false).cast<std::string>();
  return nlohmann::json::parse(text);
}

CoefficientSet coefficients_from_python(const py::handle& o, const std::string& origin) {
  return parse_coefficients(from_python(o), origin);
}

std::string relabel(std::string text, const std::string& path, const std::string& label) {
  if (path.empty()) return text;
  for (size_t at = text.find(path); at != std::string::npos; at = text.find(path, at + label.size())) {
    text.replace(at, path.size(), label);
  }
  return text;
}

void bind_samples(py::module_& m) {
  m.def(
      "write_samples",
      [](const std::string& path, const py::dict& columns, const std::string& label) {
        write_samples_csv(path, table_from_columns(columns, label));
      },
      py::arg("path"), py::arg("columns"), py::arg("label"),
      "Write columns (name -> array) as a samples CSV through the stand's SampleTable and writer.");
  m.def(
      "read_samples",
      [](const std::string& path) {
        const SampleTable t = read_samples_csv(path);
        py::dict out;
        out["time_s"] = py::array_t<double>(t.size(), t.time_s.data());
        std::vector<std::string> phase;
        phase.reserve(t.size());
        for (Phase p : t.phase) phase.emplace_back(to_string(p));
        out["phase"] = phase;
        out["step"] = py::array_t<int64_t>(t.size(), t.step.data());
        out["ref_pitch_arcsec"] = py::array_t<double>(t.size(), t.ref_pitch_arcsec.data());
        out["ref_yaw_arcsec"] = py::array_t<double>(t.size(), t.ref_yaw_arcsec.data());
        out["counts_alpha"] = py::array_t<double>(t.size(), t.counts_alpha.data());
        out["counts_beta"] = py::array_t<double>(t.size(), t.counts_beta.data());
        // An extra column of numbers as numbers (NaN for an empty cell), any other as its text.
        for (const auto& name : t.extra_names()) {
          try {
            const std::vector<double> v = t.numeric_column(name);
            out[py::str(name)] = py::array_t<double>(v.size(), v.data());
          } catch (const InputError&) {
            out[py::str(name)] = t.extra_column(name);
          }
        }
        return out;
      },
      py::arg("path"), "The columns of a samples CSV (read by the stand's reader: the same checks and messages).");
}

}  // namespace fpss::pybind
