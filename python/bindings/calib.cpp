// The calibration side of _fpss_stand: transfer function, calibrate, diagnose, design, reduce, compare, coefficient files.
// Every function calls what the command of the same name calls (stand/cli/cmd_*.cpp), nothing else.
#include <fmt/format.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "base/clock.h"
#include "base/errors.h"
#include "calib/calibrator.h"
#include "calib/coefficients.h"
#include "calib/compare.h"
#include "calib/design.h"
#include "procedures/design_procedure.h"
#include "calib/diagnosis/diagnosis.h"
#include "calib/reduction.h"
#include "calib/report.h"
#include "calib/samples.h"
#include "calib/streaming.h"
#include "calib/transfer_function.h"
#include "calib/units.h"
#include "convert.h"

namespace fpss::pybind {

namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

// A coefficient set given as a file path (read as the commands read it) or as a dict (checked alike).
CoefficientSet coefficients_arg(const py::handle& o, const std::string& what) {
  if (py::isinstance<py::str>(o) || py::hasattr(o, "__fspath__")) {
    return load_coefficients(py::str(py::module_::import("os").attr("fspath")(o)).cast<std::string>());
  }
  return coefficients_from_python(o, what);
}

// Runs `fn` on a samples file; messages naming the file name `label` instead (a DataFrame's
// temporary samples.csv is not a name the caller knows).
template <typename Fn>
auto relabeled(const std::string& path, const std::string& label, Fn fn) {
  try {
    return fn();
  } catch (const DataError& e) {
    throw DataError(relabel(e.what(), path, label));
  } catch (const InputError& e) {
    throw InputError(relabel(e.what(), path, label));
  }
}

Array apply(const Array& in, const std::function<double(double)>& f) {
  Array out(std::vector<py::ssize_t>(in.shape(), in.shape() + in.ndim()));
  double* o = out.mutable_data();
  const double* x = in.data();
  for (py::ssize_t i = 0; i < in.size(); ++i) o[i] = f(x[i]);
  return out;
}

// fpss-stand calibrate --data PATH --out OUT: calibrate_csv, then the coefficient file as the
// command writes it (calibrated_at, init, truth_comparison), saved by the same writer when `out` is given.
py::tuple calibrate_file(const std::string& path, const std::string& label, const std::string& method,
                         const py::object& init, const py::object& truth, std::optional<double> count_noise_counts,
                         const std::string& unit, const std::string& out) {
  CalibrationOptions opts;
  const auto m = parse_method(method);
  if (!m) throw InputError(fmt::format("method '{}': expected differences or absolute", method));
  opts.method = *m;
  std::optional<CoefficientSet> truth_set;
  if (!init.is_none()) opts.init = coefficients_arg(init, "init");
  if (!truth.is_none()) truth_set = coefficients_arg(truth, "truth");
  opts.unit = !unit.empty() ? unit : opts.init ? opts.init->unit : truth_set ? truth_set->unit : std::string();
  if (count_noise_counts) {
    opts.count_noise_counts = *count_noise_counts;
    opts.count_noise_source = "command line";
  }
  CalibrationReport rep = relabeled(path, label, [&] {
    py::gil_scoped_release release;  // the fit touches no Python object: other threads run meanwhile
    return calibrate_csv(path, opts);
  });
  if (label != path) rep.source = label;
  CoefficientSet set = rep.coefficients();
  set.extra["calibrated_at"] = utc_now_iso();
  if (py::isinstance<py::str>(init)) set.extra["init"] = init.cast<std::string>();
  std::string text = summary_text(rep);
  if (truth_set) {
    const TruthComparison cmp = compare_to_truth(rep, *truth_set);
    const std::string truth_name = py::isinstance<py::str>(truth) ? truth.cast<std::string>() : std::string("truth");
    set.extra["truth_comparison"] = {
        {"truth", truth_name},
        {"pitch", {{"max_abs_arcsec", cmp.pitch.max_abs_arcsec}, {"rms_arcsec", cmp.pitch.rms_arcsec}}},
        {"yaw", {{"max_abs_arcsec", cmp.yaw.max_abs_arcsec}, {"rms_arcsec", cmp.yaw.rms_arcsec}}}};
    text += truth_text(cmp, truth_name);
  }
  if (!out.empty()) save_coefficients(out, set);
  return py::make_tuple(to_python(to_json(set)), text);
}

// fpss-stand diagnose --model MODEL --data PATH --out GAP.json: GAP.json's content.
py::object diagnose_file(const py::object& model, const std::string& model_name, const std::string& path,
                         const std::string& label, double settle_s, double max_skew_s) {
  const CoefficientSet set = coefficients_arg(model, "model");
  DiagnosisOptions opts;
  opts.settle_s = settle_s;
  opts.max_skew_s = max_skew_s;
  const Diagnosis d = relabeled(path, label, [&] {
    py::gil_scoped_release release;
    DiagnosisColumns cols = read_diagnosis_columns(path);
    cols.origin = label;
    return diagnose(std::move(cols), set, opts);
  });
  nlohmann::ordered_json j = d.to_json();
  j["model"] = model_name;
  return to_python(j);
}

// The one reduction (calib/reduction.h) of a samples file: its dwells as columns, the outlier counts.
py::dict reduce_file(const std::string& path, const std::string& label, const py::object& calibration,
                     std::optional<double> count_noise_counts, bool reject_outliers) {
  ReductionOptions opts;
  if (!calibration.is_none()) opts = reduction_options_of(coefficients_arg(calibration, "calibration").extra, "calibration");
  if (count_noise_counts) {
    opts.count_noise_counts = count_noise_counts;
    opts.count_noise_source = "caller";
  }
  opts.reject_outliers = reject_outliers;
  const Reduction r = relabeled(path, label, [&] {
    SampleTable t = read_samples_csv(path);
    t.origin = label;
    return reduce(t, opts);
  });
  std::vector<int64_t> step, samples, outliers;
  std::vector<std::string> phase;
  std::vector<double> cols[10];
  for (const Dwell& d : r.dwells) {
    step.push_back(d.step);
    phase.emplace_back(to_string(d.phase));
    samples.push_back(static_cast<int64_t>(d.samples));
    outliers.push_back(static_cast<int64_t>(d.outliers));
    const double v[10] = {d.t_start_s, d.t_end_s, d.counts_alpha, d.counts_beta, d.ref_pitch_arcsec,
                          d.ref_yaw_arcsec, d.sd_counts_alpha, d.sd_counts_beta, d.sd_ref_pitch_arcsec,
                          d.sd_ref_yaw_arcsec};
    for (int k = 0; k < 10; ++k) cols[k].push_back(v[k]);
  }
  const char* names[10] = {"t_start_s", "t_end_s", "counts_alpha", "counts_beta", "ref_pitch_arcsec",
                           "ref_yaw_arcsec", "sd_counts_alpha", "sd_counts_beta", "sd_ref_pitch_arcsec",
                           "sd_ref_yaw_arcsec"};
  py::dict dwells;
  dwells["step"] = py::array_t<int64_t>(step.size(), step.data());
  dwells["phase"] = phase;
  dwells["samples"] = py::array_t<int64_t>(samples.size(), samples.data());
  dwells["outlier_frames"] = py::array_t<int64_t>(outliers.size(), outliers.data());
  for (int k = 0; k < 10; ++k) dwells[names[k]] = py::array_t<double>(cols[k].size(), cols[k].data());
  py::dict out;
  out["dwells"] = dwells;
  out["outliers"] = to_python(r.outliers.to_json());
  return out;
}

py::dict axis_comparison(const AxisComparison& a) {
  py::dict d;
  d["counts"] = py::array_t<double>(a.counts.size(), a.counts.data());
  d["angle_a_arcsec"] = py::array_t<double>(a.angle_a_arcsec.size(), a.angle_a_arcsec.data());
  d["diff_arcsec"] = py::array_t<double>(a.diff_arcsec.size(), a.diff_arcsec.data());
  return d;
}

py::object design_py(const py::object& prior, const py::list& also_for, const py::dict& kw) {
  DesignInputs in;
  in.prior = coefficients_arg(prior, "prior");
  for (const auto& o : also_for) {
    CoefficientSet s = coefficients_arg(o, "also_for");
    in.also_for.push_back(std::move(s));
  }
  auto num = [&](const char* key, double& v) { if (kw.contains(key)) v = kw[key].cast<double>(); };
  num("target_sigma_arcsec", in.target_sigma_arcsec);
  num("extent_deg", in.extent_deg);
  num("candidate_step_deg", in.candidate_step_deg);
  num("rate_deg_s", in.rate_deg_s);
  num("accel_deg_s2", in.accel_deg_s2);
  num("settle_s", in.settle_s);
  num("frame_rate_hz", in.frame_rate_hz);
  num("count_noise_counts", in.count_noise_counts);
  num("ref_noise_arcsec", in.ref_noise_arcsec);
  if (kw.contains("samples_choices")) in.samples_choices = kw["samples_choices"].cast<std::vector<int>>();
  if (kw.contains("max_offsets_per_axis")) in.max_offsets_per_axis = kw["max_offsets_per_axis"].cast<int>();
  if (!(std::isfinite(in.target_sigma_arcsec) && in.target_sigma_arcsec > 0)) {
    throw InputError(fmt::format("design: target_sigma_arcsec {}: expected a number > 0", in.target_sigma_arcsec));
  }
  ExperimentDesign d;
  try {
    py::gil_scoped_release release;
    d = design_experiment(in);
  } catch (const std::invalid_argument& e) {
    throw InputError(fmt::format("design: {}", e.what()));
  }
  DesignSources src{"keyword arguments", kw.contains("count_noise_counts") ? "keyword argument" : "default",
                    in.prior.unit.empty() ? "prior" : in.prior.unit};
  const nlohmann::ordered_json j = design_report_json(d, in, src);
  return to_python(j);
}

}  // namespace

void bind_calib(py::module_& m) {
  m.def(
      "transfer_function",
      [](const std::array<double, 8>& c, const Array& counts) {
        const AxisModel model(c);
        return apply(counts, [&](double n) { return model.angle_arcsec(n); });
      },
      py::arg("coeffs"), py::arg("counts"), "Angle (arcsec) for counts under C1..C8 (paper eq. 1; radians, rad/count).");
  m.def(
      "inverse_transfer_function",
      [](const std::array<double, 8>& c, const Array& angle_arcsec, double lo, double hi) {
        const AxisModel model(c);
        model.check_monotonic(lo, hi);
        return apply(angle_arcsec, [&](double a) {
          try {
            return model.counts_for_angle_unchecked(arcsec_to_rad(a), lo, hi);
          } catch (const std::out_of_range&) {
            throw InputError(fmt::format("angle {} arcsec: not reached within counts [{}, {}]", a, lo, hi));
          }
        });
      },
      py::arg("coeffs"), py::arg("angle_arcsec"), py::arg("lo_counts") = kCountsMin, py::arg("hi_counts") = kCountsMax,
      "Counts whose angle is angle_arcsec (the inverse over [lo, hi], where the function is monotonic).");
  m.def("calibrate_file", &calibrate_file, py::arg("path"), py::arg("label"), py::arg("method"), py::arg("init"),
        py::arg("truth"), py::arg("count_noise_counts"), py::arg("unit"), py::arg("out"));
  m.def("diagnose_file", &diagnose_file, py::arg("model"), py::arg("model_name"), py::arg("path"), py::arg("label"),
        py::arg("settle_s"), py::arg("max_skew_s"));
  m.def("reduce_file", &reduce_file, py::arg("path"), py::arg("label"), py::arg("calibration"),
        py::arg("count_noise_counts"), py::arg("reject_outliers"));
  m.def("design", &design_py, py::arg("prior"), py::arg("also_for"), py::arg("kwargs"));
  m.def(
      "compare",
      [](const py::object& a, const py::object& b, double range_deg) {
        const CalibrationComparison c = compare_calibrations(coefficients_arg(a, "a"), coefficients_arg(b, "b"), range_deg);
        py::dict out;
        out["summary"] = to_python(c.detail_json());
        out["alpha"] = axis_comparison(c.alpha);
        out["beta"] = axis_comparison(c.beta);
        return out;
      },
      py::arg("a"), py::arg("b"), py::arg("range_deg") = kDefaultCompareRangeDeg);
  m.def("load_coefficients", [](const std::string& path) { return to_python(to_json(load_coefficients(path))); },
        py::arg("path"));
  // A fitted set's Table 1 and coefficients as the command prints them (calib/report.h); "" for a published set.
  m.def("calibration_summary", [](const py::object& o) { return summary_text(coefficients_from_python(o, "calibration")); },
        py::arg("coefficients"));
  m.def("check_coefficients", [](const py::object& o, const std::string& origin) {
    return to_python(to_json(coefficients_from_python(o, origin)));
  });
  m.def("save_coefficients", [](const std::string& path, const py::object& o) {
    save_coefficients(path, coefficients_from_python(o, path));
  });
  m.def("published_names", &published_names);
  m.def("load_published", [](const std::string& name) { return to_python(to_json(load_published(name))); },
        py::arg("name"));
  m.def("published_dir", [] { return published_dir().string(); });
}

}  // namespace fpss::pybind
