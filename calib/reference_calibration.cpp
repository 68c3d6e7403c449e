#include "calib/reference_calibration.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <tuple>
#include <set>

#include "base/errors.h"
#include "base/json_file.h"
#include "base/sha256.h"
#include "base/text_file.h"
#include "calib/units.h"

namespace fpss {

namespace {

// Reading minus true angle of one axis (arcsec) and its derivatives by its own and the other
// axis's true angle. Radians inside the trigonometry.
struct AxisError {
  double error_arcsec, d_own, d_other;
};

AxisError axis_error(const ReferenceAxis& a, double own_arcsec, double other_arcsec) {
  const double n = std::sin(arcsec_to_rad(a.nonorthogonality_arcsec.value));
  const double s = 1e-6 * a.scale_factor_ppm.value;
  AxisError e{a.zero_arcsec.value + s * own_arcsec + n * other_arcsec, s, n};
  const double theta = arcsec_to_rad(own_arcsec);
  for (const CyclicTerm& c : a.cyclic) {
    const double arg = c.harmonic * theta + c.phase_rad.value;
    e.error_arcsec += c.amplitude_arcsec.value * std::sin(arg);
    e.d_own += c.amplitude_arcsec.value * std::cos(arg) * c.harmonic * kRadPerArcsec;
  }
  return e;
}

// Each term's contribution to the standard uncertainty of one axis's error at these true angles:
// its u times its sensitivity, named for a budget ("<axis> scale factor", ...).
std::vector<BudgetEntry> axis_terms(const ReferenceAxis& a, const std::string& axis, double own_arcsec,
                                    double other_arcsec) {
  const double n_rad = arcsec_to_rad(a.nonorthogonality_arcsec.value);
  const auto term = [&](const std::string& what, double sensitivity, double u) {
    return BudgetEntry{"reference calibration: " + axis + " " + what, 'B', sensitivity, std::abs(sensitivity) * u,
                       std::numeric_limits<double>::infinity()};
  };
  std::vector<BudgetEntry> out{
      term("scale factor", 1e-6 * own_arcsec, a.scale_factor_ppm.u),
      term("non-orthogonality", std::cos(n_rad) * other_arcsec, arcsec_to_rad(a.nonorthogonality_arcsec.u)),
      term("zero", 1.0, a.zero_arcsec.u),
  };
  const double theta = arcsec_to_rad(own_arcsec);
  for (const CyclicTerm& c : a.cyclic) {
    const double arg = c.harmonic * theta + c.phase_rad.value;
    out.push_back(term(fmt::format("cyclic harmonic {} amplitude", c.harmonic), std::sin(arg), c.amplitude_arcsec.u));
    out.push_back(term(fmt::format("cyclic harmonic {} phase", c.harmonic), c.amplitude_arcsec.value * std::cos(arg),
                       c.phase_rad.u));
  }
  return out;
}

double axis_u(const ReferenceAxis& a, double own_arcsec, double other_arcsec) {
  return root_sum_square(axis_terms(a, "", own_arcsec, other_arcsec));
}

// Reads one JSON object's keys strictly: each key taken once, anything left over is an error.
class Keys {
 public:
  Keys(const nlohmann::json& j, std::string origin, std::string prefix)
      : j_(j), origin_(std::move(origin)), prefix_(std::move(prefix)) {
    if (!j_.is_object()) fail("", "expected an object");
  }
  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    const std::string k = prefix_.empty() ? key : key.empty() ? prefix_ : prefix_ + "." + key;
    throw InputError(fmt::format("{}: key \"{}\": {}", origin_, k, what));
  }
  std::string path(const std::string& key) const { return prefix_.empty() ? key : prefix_ + "." + key; }
  const nlohmann::json& at(const std::string& key) {
    if (!j_.contains(key)) fail(key, "missing");
    taken_.insert(key);
    return j_.at(key);
  }
  double number(const std::string& key, double lo, double hi) {
    const nlohmann::json& v = at(key);
    if (!v.is_number()) fail(key, "expected a number");
    const double x = v.get<double>();
    if (!std::isfinite(x) || x < lo || x > hi) fail(key, fmt::format("{} is outside [{}, {}]", x, lo, hi));
    return x;
  }
  std::string text(const std::string& key) {
    const nlohmann::json& v = at(key);
    if (!v.is_string() || v.get<std::string>().empty() || v.get<std::string>().size() > 200) {
      fail(key, "expected a non-empty string of at most 200 characters");
    }
    return v.get<std::string>();
  }
  void done() const {
    for (const auto& [k, v] : j_.items()) {
      if (!taken_.count(k)) fail(k, "unknown key");
    }
  }

 private:
  const nlohmann::json& j_;
  std::string origin_, prefix_;
  std::set<std::string> taken_;
};

CertifiedValue certified(Keys& parent, const std::string& key, double limit, const std::string& origin) {
  Keys k(parent.at(key), origin, parent.path(key));
  CertifiedValue v{k.number("value", -limit, limit), k.number("u", 0, limit)};
  k.done();
  return v;
}

ReferenceAxis parse_axis(Keys& top, const std::string& name, const std::string& origin) {
  Keys k(top.at(name), origin, name);
  ReferenceAxis a;
  a.scale_factor_ppm = certified(k, "scale_factor_ppm", kMaxReferenceScalePpm, origin);
  a.nonorthogonality_arcsec = certified(k, "nonorthogonality_arcsec", kMaxReferenceAngleArcsec, origin);
  a.zero_arcsec = certified(k, "zero_arcsec", kMaxReferenceAngleArcsec, origin);
  const nlohmann::json& list = k.at("cyclic");
  if (!list.is_array()) k.fail("cyclic", "expected a list of {harmonic, amplitude_arcsec, phase_rad}");
  if (list.size() > kMaxReferenceCyclicTerms) {
    k.fail("cyclic", fmt::format("{} terms; at most {}", list.size(), kMaxReferenceCyclicTerms));
  }
  for (size_t i = 0; i < list.size(); ++i) {
    Keys t(list[i], origin, fmt::format("{}.cyclic[{}]", name, i));
    CyclicTerm c;
    const double h = t.number("harmonic", 1, kMaxReferenceHarmonic);
    if (h != std::floor(h)) t.fail("harmonic", "expected a whole number");
    c.harmonic = static_cast<int>(h);
    c.amplitude_arcsec = certified(t, "amplitude_arcsec", kMaxReferenceAngleArcsec, origin);
    c.phase_rad = certified(t, "phase_rad", 2 * std::numbers::pi, origin);
    t.done();
    a.cyclic.push_back(c);
  }
  k.done();
  return a;
}

}  // namespace

std::pair<double, double> ReferenceCalibration::reading_from_true(double p, double y) const {
  return {p + axis_error(pitch, p, y).error_arcsec, y + axis_error(yaw, y, p).error_arcsec};
}

std::pair<double, double> ReferenceCalibration::true_from_reading(double rp, double ry) const {
  // Newton on reading_from_true(t) = r from t = r: the errors are small and smooth, so a few
  // steps reach the 1e-9 arcsec the check asks for.
  double p = rp, y = ry;
  for (int it = 0; it < 50; ++it) {
    const AxisError ep = axis_error(pitch, p, y), ey = axis_error(yaw, y, p);
    const double fp = p + ep.error_arcsec - rp, fy = y + ey.error_arcsec - ry;
    const double a = 1 + ep.d_own, b = ep.d_other, c = ey.d_other, d = 1 + ey.d_own;
    const double det = a * d - b * c;
    const double dp = (d * fp - b * fy) / det, dy = (a * fy - c * fp) / det;
    p -= dp;
    y -= dy;
    if (std::abs(dp) < 1e-10 && std::abs(dy) < 1e-10) break;
  }
  return {p, y};
}

std::pair<double, double> ReferenceCalibration::u_true_arcsec(double p, double y) const {
  return {axis_u(pitch, p, y), axis_u(yaw, y, p)};
}

nlohmann::json ReferenceCalibration::identity() const {
  return {{"file", file}, {"sha256", sha256}, {"certificate", certificate}, {"date", date}, {"lab", lab}};
}

void correct_reference_angles(const ReferenceCalibration& r, const AxisMapping& mount, double& ref_pitch_arcsec,
                              double& ref_yaw_arcsec) {
  const auto [p, y] = mount.stand_from_sensor(ref_pitch_arcsec, ref_yaw_arcsec);
  const auto [tp, ty] = r.true_from_reading(p, y);
  std::tie(ref_pitch_arcsec, ref_yaw_arcsec) = mount.sensor_from_stand(tp, ty);
}

namespace {

bool sees_pitch(const AxisMapping& mount, int sensor_axis) {
  return (sensor_axis == 0) == (mount.pitch_axis == AxisMapping::alpha);
}

std::pair<double, double> stand_angles(const AxisMapping& mount, int sensor_axis, double angle_arcsec, double other_arcsec) {
  return sensor_axis == 0 ? mount.stand_from_sensor(angle_arcsec, other_arcsec)
                          : mount.stand_from_sensor(other_arcsec, angle_arcsec);
}

}  // namespace

std::vector<BudgetEntry> reference_terms_at(const ReferenceCalibration& r, const AxisMapping& mount, int sensor_axis,
                                            double angle_arcsec, double other_arcsec) {
  const auto [p, y] = stand_angles(mount, sensor_axis, angle_arcsec, other_arcsec);
  return sees_pitch(mount, sensor_axis) ? axis_terms(r.pitch, "pitch", p, y) : axis_terms(r.yaw, "yaw", y, p);
}

double reference_worst_other_arcsec(const ReferenceCalibration& r, const AxisMapping& mount, int sensor_axis,
                                    double angle_arcsec, double other_extent_arcsec) {
  double worst_other = 0, worst_u = -1;
  for (double other : {-other_extent_arcsec, 0.0, other_extent_arcsec}) {
    if (const double u = root_sum_square(reference_terms_at(r, mount, sensor_axis, angle_arcsec, other)); u > worst_u) {
      worst_u = u;
      worst_other = other;
    }
  }
  return worst_other;
}

std::vector<BudgetEntry> reference_budget(const ReferenceCalibration& r, const AxisMapping& mount, int sensor_axis,
                                          double angle_arcsec, double other_extent_arcsec) {
  return reference_terms_at(r, mount, sensor_axis, angle_arcsec,
                            reference_worst_other_arcsec(r, mount, sensor_axis, angle_arcsec, other_extent_arcsec));
}

double reference_error_arcsec(const ReferenceCalibration& r, const AxisMapping& mount, int sensor_axis,
                              double angle_arcsec, double other_arcsec) {
  const auto [p, y] = stand_angles(mount, sensor_axis, angle_arcsec, other_arcsec);
  const auto [rp, ry] = r.reading_from_true(p, y);
  return sees_pitch(mount, sensor_axis) ? rp - p : ry - y;
}

double reference_u_arcsec(const ReferenceCalibration& r, const AxisMapping& mount, int sensor_axis, double angle_arcsec,
                          double other_extent_arcsec) {
  return root_sum_square(reference_budget(r, mount, sensor_axis, angle_arcsec, other_extent_arcsec));
}

ReferenceCalibration parse_reference_calibration(const nlohmann::json& j, const std::string& origin) {
  Keys k(j, origin, "");
  ReferenceCalibration r;
  r.file = origin;
  r.certificate = k.text("certificate");
  r.date = k.text("date");
  r.lab = k.text("lab");
  r.pitch = parse_axis(k, "pitch", origin);
  r.yaw = parse_axis(k, "yaw", origin);
  k.done();
  return r;
}

ReferenceCalibration load_reference_calibration(const std::filesystem::path& path) {
  // The text once: its bytes are what the sha256 names, and what is parsed (read_json_file's limits).
  const std::string text = read_text_file(path, "reference calibration file", kMaxConfigFileBytes);
  ReferenceCalibration r = parse_reference_calibration(parse_json_text(text, path.string()), path.string());
  r.sha256 = sha256_hex(text);
  return r;
}

}  // namespace fpss
