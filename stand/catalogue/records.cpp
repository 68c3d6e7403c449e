// The catalogue's records read from and written as JSON (calibration.json's residuals, coefficient files).
#include <fmt/format.h>

#include <cmath>

#include "base/errors.h"
#include "calib/coefficients.h"
#include "stand/catalogue/catalogue.h"

namespace fpss {

bool AxisResidualStats::empty() const {
  return !mean_abs_arcsec && !sd_arcsec && !max_abs_arcsec && !rms_arcsec && !points && !range_lo_deg &&
         !range_hi_deg;
}

AxisResidualStats AxisResidualStats::from_json(const nlohmann::json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(fmt::format("{}: expected an object of residual statistics", where));
  AxisResidualStats s;
  auto num = [&](const char* key) -> std::optional<double> {
    if (!j.contains(key) || j[key].is_null()) return std::nullopt;
    if (!j[key].is_number() || !std::isfinite(j[key].get<double>())) {
      throw InputError(fmt::format("{}: \"{}\" must be a finite number, got {}", where, key, j[key].dump()));
    }
    return j[key].get<double>();
  };
  s.mean_abs_arcsec = num("mean_abs_arcsec");
  s.sd_arcsec = num("sd_arcsec");
  s.max_abs_arcsec = num("max_abs_arcsec");
  s.rms_arcsec = num("rms_arcsec");
  if (const auto pts = num("points")) {
    if (*pts < 0 || *pts != std::floor(*pts)) {
      throw InputError(fmt::format("{}: \"points\" must be a whole number >= 0, got {}", where, *pts));
    }
    s.points = static_cast<int64_t>(*pts);
  }
  if (j.contains("range_deg") && !j["range_deg"].is_null()) {
    const auto& r = j["range_deg"];
    if (!r.is_array() || r.size() != 2 || !r[0].is_number() || !r[1].is_number() ||
        !std::isfinite(r[0].get<double>()) || !std::isfinite(r[1].get<double>()) ||
        r[0].get<double>() > r[1].get<double>()) {
      throw InputError(fmt::format("{}: \"range_deg\" must be [lo, hi] in degrees, lo <= hi, got {}", where,
                                   r.dump()));
    }
    s.range_lo_deg = r[0].get<double>();
    s.range_hi_deg = r[1].get<double>();
  }
  return s;
}

nlohmann::json AxisResidualStats::to_json() const {
  nlohmann::json j = nlohmann::json::object();
  if (mean_abs_arcsec) j["mean_abs_arcsec"] = *mean_abs_arcsec;
  if (sd_arcsec) j["sd_arcsec"] = *sd_arcsec;
  if (max_abs_arcsec) j["max_abs_arcsec"] = *max_abs_arcsec;
  if (rms_arcsec) j["rms_arcsec"] = *rms_arcsec;
  if (points) j["points"] = *points;
  if (range_lo_deg && range_hi_deg) j["range_deg"] = {*range_lo_deg, *range_hi_deg};
  return j;
}

CalibrationRecord CalibrationRecord::from_calibration_json(const nlohmann::json& cal,
                                                           const std::string& origin) {
  const CoefficientSet set = parse_coefficients(cal, origin);  // validates C1..C8 of both axes
  CalibrationRecord c;
  c.unit = set.unit;
  c.coefficients = cal;
  if (cal.contains("method") && cal["method"].is_string()) c.method = cal["method"].get<std::string>();
  if (cal.contains("date") && cal["date"].is_string()) c.date_utc = cal["date"].get<std::string>();
  if (cal.contains("residuals")) {
    const auto& r = cal["residuals"];
    if (!r.is_object()) throw InputError(fmt::format("{}: \"residuals\" must be an object", origin));
    for (const char* axis : {"pitch", "yaw"}) {
      if (!r.contains(axis) || r[axis].is_null()) continue;
      auto stats = AxisResidualStats::from_json(r[axis], fmt::format("{}: residuals.{}", origin, axis));
      if (!stats.empty()) (axis[0] == 'p' ? c.pitch : c.yaw) = stats;
    }
  }
  return c;
}

}  // namespace fpss
