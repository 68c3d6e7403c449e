// What both catalogue backends share about records: the rules a record keeps before it is written
// and the values the catalogue fills in, the columns records are stored in, and a record read back
// from a row of either backend's result.
#pragma once
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "stand/catalogue/catalogue.h"

namespace fpss {

// InputError for an empty serial.
void require_unit(const std::string& serial);
// std::invalid_argument for a run start without its id; InputError without its unit.
void check_run_start(const RunStart& run);
// std::invalid_argument for an outcome that is not a final one.
// std::invalid_argument for a calibration no backend may store (unknown source, a run's without
// its run id, an import with one, coefficients that are not an object).
void check_calibration(const CalibrationRecord& cal);
// The same, and std::invalid_argument for anything but an import with its date.
void check_import(const CalibrationRecord& cal);

// The records as the catalogue stores them: a run's start time (now when empty) and its folder made
// absolute; a calibration's or an acceptance's entry time (now), its date (now when empty) and host
// (this one when empty), and a calibration's source_ref (its run id when empty).
RunStart as_recorded(RunStart run);
CalibrationRecord as_recorded(CalibrationRecord cal);
AcceptanceRecord as_recorded(AcceptanceRecord acc);

// The residual statistics stored per axis, as columns `<axis>_<name>` (pitch_mean_abs_arcsec, ...).
inline constexpr const char* kStatColumns[] = {"mean_abs_arcsec", "sd_arcsec",    "max_abs_arcsec", "rms_arcsec",
                                               "points",          "range_lo_deg", "range_hi_deg"};

// Every axis's statistic columns, comma-separated, each written with `format` from the axis and the
// statistic: "{}_{}" gives the names, ":{}_{}" SQLite's named parameters.
std::string stat_columns(const char* format = "{}_{}");

// The columns each record is selected with, in the order of the record's fields.
inline constexpr const char* kRunColumns =
    "run_id, unit, procedure, procedure_hash, started_utc, ended_utc, outcome, run_dir, emulated, "
    "stand, software_version, resumes, pid, host, operator";
const std::string& calibration_columns();
inline constexpr const char* kAcceptanceColumns =
    "id, unit, run_id, passed, date_utc, recorded_utc, certificate_json, stand, host, operator";

// The records read from one row of a result. `Row` reads a column by name, as a backend's types
// give it: text(c), opt_text(c), integer(c), opt_integer(c), opt_real(c) and flag(c) (a boolean).
// Each record is built in the order of its fields, which is the order of its columns above.
template <typename Row>
std::optional<AxisResidualStats> stats_of_row(const Row& r, const std::string& axis) {
  auto real = [&](const char* k) { return r.opt_real(axis + "_" + k); };
  const AxisResidualStats s{
      real("mean_abs_arcsec"),         real("sd_arcsec"),    real("max_abs_arcsec"), real("rms_arcsec"),
      r.opt_integer(axis + "_points"), real("range_lo_deg"), real("range_hi_deg")};
  if (s.empty()) return std::nullopt;
  return s;
}

template <typename Row>
RunRecord run_of_row(const Row& r) {
  return RunRecord{r.text("run_id"),      r.text("unit"),          r.text("procedure"),        r.text("procedure_hash"),
                   r.text("started_utc"), r.opt_text("ended_utc"), RunRecord::outcome_of(r.text("outcome"), "catalogue runs.outcome"), r.text("run_dir"),
                   r.flag("emulated"),    r.text("stand"),         r.text("software_version"), r.integer("resumes"),
                   r.integer("pid"),      r.text("host"),          r.text("operator")};
}

template <typename Row>
CalibrationRecord calibration_of_row(const Row& r) {
  return CalibrationRecord{r.integer("id"),          r.text("unit"),
                           r.text("source"),         r.opt_text("run_id"),
                           r.text("source_ref"),     r.text("label"),
                           r.text("date_utc"),       r.text("recorded_utc"),
                           r.text("method"),         nlohmann::json::parse(r.text("coefficients_json")),
                           stats_of_row(r, "pitch"), stats_of_row(r, "yaw"),
                           r.text("stand"),          r.text("host"),
                           r.text("operator")};
}

template <typename Row>
AcceptanceRecord acceptance_of_row(const Row& r) {
  return AcceptanceRecord{r.integer("id"),
                          r.text("unit"),
                          r.opt_text("run_id"),
                          r.flag("passed"),
                          r.text("date_utc"),
                          r.text("recorded_utc"),
                          nlohmann::json::parse(r.text("certificate_json")),
                          r.text("stand"),
                          r.text("host"),
                          r.text("operator")};
}

}  // namespace fpss
