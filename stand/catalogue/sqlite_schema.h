// The catalogue's SQLite schema, as versioned migrations (the PostgreSQL ones are numbered alike).
#pragma once
#include <iterator>

namespace fpss::sqlite_schema {

// Schema migrations: kMigrations[v] takes a catalogue from user_version v to v + 1. Each runs
// inside the IMMEDIATE transaction that also sets user_version, so two processes opening a
// fresh file at once cannot both create it, and a crash leaves either v or v + 1.
// A later version appends a step here (and bumps Catalogue::kSchemaVersion).
inline const char* const kMigrations[] = {
    // 0 -> 1
    R"sql(
CREATE TABLE IF NOT EXISTS units (
  serial          TEXT PRIMARY KEY NOT NULL CHECK (serial <> ''),
  first_seen_utc  TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS runs (
  run_id            TEXT PRIMARY KEY NOT NULL CHECK (run_id <> ''),
  unit              TEXT NOT NULL REFERENCES units(serial),
  procedure         TEXT NOT NULL,
  procedure_hash    TEXT NOT NULL,
  started_utc       TEXT NOT NULL,
  ended_utc         TEXT,
  outcome           TEXT NOT NULL,
  run_dir           TEXT NOT NULL,
  emulated          INTEGER NOT NULL CHECK (emulated IN (0, 1)),
  stand             TEXT NOT NULL DEFAULT '',
  software_version  TEXT NOT NULL,
  resumes           INTEGER NOT NULL DEFAULT 0,
  pid               INTEGER NOT NULL DEFAULT 0,
  host              TEXT NOT NULL DEFAULT ''
);
CREATE INDEX IF NOT EXISTS runs_by_unit ON runs(unit, started_utc);
CREATE TABLE IF NOT EXISTS calibrations (
  id                     INTEGER PRIMARY KEY AUTOINCREMENT,
  unit                   TEXT NOT NULL REFERENCES units(serial),
  source                 TEXT NOT NULL CHECK (source IN ('run', 'import')),
  run_id                 TEXT REFERENCES runs(run_id),
  source_ref             TEXT NOT NULL,
  label                  TEXT NOT NULL DEFAULT '',
  date_utc               TEXT NOT NULL,
  recorded_utc           TEXT NOT NULL,
  method                 TEXT NOT NULL,
  coefficients_json      TEXT NOT NULL CHECK (json_valid(coefficients_json)),
  pitch_mean_abs_arcsec  REAL,
  pitch_sd_arcsec        REAL,
  pitch_max_abs_arcsec   REAL,
  pitch_rms_arcsec       REAL,
  pitch_points           INTEGER,
  pitch_range_lo_deg     REAL,
  pitch_range_hi_deg     REAL,
  yaw_mean_abs_arcsec    REAL,
  yaw_sd_arcsec          REAL,
  yaw_max_abs_arcsec     REAL,
  yaw_rms_arcsec         REAL,
  yaw_points             INTEGER,
  yaw_range_lo_deg       REAL,
  yaw_range_hi_deg       REAL,
  CHECK ((source = 'run') = (run_id IS NOT NULL))
);
CREATE INDEX IF NOT EXISTS calibrations_by_unit ON calibrations(unit, date_utc, id);
CREATE TABLE IF NOT EXISTS acceptances (
  id                INTEGER PRIMARY KEY AUTOINCREMENT,
  unit              TEXT NOT NULL REFERENCES units(serial),
  run_id            TEXT REFERENCES runs(run_id),
  passed            INTEGER NOT NULL CHECK (passed IN (0, 1)),
  date_utc          TEXT NOT NULL,
  recorded_utc      TEXT NOT NULL,
  certificate_json  TEXT NOT NULL CHECK (json_valid(certificate_json))
);
CREATE INDEX IF NOT EXISTS acceptances_by_unit ON acceptances(unit, date_utc, id);
)sql",
    // 1 -> 2: every record names the stand and host that wrote it (a fleet shares one catalogue).
    R"sql(
ALTER TABLE calibrations ADD COLUMN stand TEXT NOT NULL DEFAULT '';
ALTER TABLE calibrations ADD COLUMN host TEXT NOT NULL DEFAULT '';
ALTER TABLE acceptances ADD COLUMN stand TEXT NOT NULL DEFAULT '';
ALTER TABLE acceptances ADD COLUMN host TEXT NOT NULL DEFAULT '';
CREATE INDEX IF NOT EXISTS runs_by_stand ON runs(stand, started_utc);
)sql",
};

}  // namespace fpss::sqlite_schema
