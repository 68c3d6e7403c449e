// The rules a record keeps before either backend writes it, the values the catalogue fills in, and
// the columns records are stored in.
#include "stand/catalogue/record_rules.h"

#include <fmt/format.h>

#include <filesystem>
#include <stdexcept>

#include "base/clock.h"
#include "base/errors.h"
#include "procedures/recorder.h"

namespace fpss {

void require_unit(const std::string& serial) {
  if (serial.empty()) throw InputError("unit serial must not be empty");
}

void check_run_start(const RunStart& run) {
  if (run.run_id.empty()) throw std::invalid_argument("record_run_start: empty run id");
  require_unit(run.unit);
}

void check_calibration(const CalibrationRecord& cal) {
  require_unit(cal.unit);
  if (cal.source != "run" && cal.source != "import") {
    throw std::invalid_argument(fmt::format("calibration source must be run or import, not \"{}\"", cal.source));
  }
  if ((cal.source == "run") != cal.run_id.has_value()) {
    throw std::invalid_argument("a calibration from a run names its run id, an import none");
  }
  if (!cal.coefficients.is_object()) throw std::invalid_argument("calibration coefficients must be a JSON object");
}

void check_import(const CalibrationRecord& cal) {
  check_calibration(cal);
  if (cal.source != "import") throw std::invalid_argument("record_import_once: the calibration is not an import");
  if (cal.date_utc.empty()) throw std::invalid_argument("record_import_once: an import needs its date");
}

RunStart as_recorded(RunStart run) {
  if (run.started_utc.empty()) run.started_utc = utc_now_iso();
  if (!run.run_dir.empty()) run.run_dir = std::filesystem::absolute(run.run_dir).lexically_normal();
  return run;
}

CalibrationRecord as_recorded(CalibrationRecord cal) {
  cal.recorded_utc = utc_now_iso();
  if (cal.date_utc.empty()) cal.date_utc = cal.recorded_utc;
  if (cal.source_ref.empty() && cal.run_id) cal.source_ref = *cal.run_id;
  if (cal.host.empty()) cal.host = this_host();
  return cal;
}

AcceptanceRecord as_recorded(AcceptanceRecord acc) {
  acc.recorded_utc = utc_now_iso();
  if (acc.date_utc.empty()) acc.date_utc = acc.recorded_utc;
  if (acc.host.empty()) acc.host = this_host();
  return acc;
}

std::string stat_columns(const char* format) {
  std::string out;
  for (const char* axis : {"pitch", "yaw"}) {
    for (const char* k : kStatColumns) {
      if (!out.empty()) out += ", ";
      out += fmt::format(fmt::runtime(format), axis, k);
    }
  }
  return out;
}

const std::string& calibration_columns() {
  static const std::string columns =
      "id, unit, source, run_id, source_ref, label, date_utc, recorded_utc, method, coefficients_json, stand, "
      "host, operator, " +
      stat_columns();
  return columns;
}

}  // namespace fpss
