// The catalogue's PostgreSQL schema, as versioned migrations numbered like the SQLite ones.
#pragma once
#include <iterator>

namespace fpss::postgres_schema {

// kMigrations[v] takes the database from schema_version v to v + 1. They run in one transaction
// under an advisory lock, so stands opening a fresh database at once apply them once; PostgreSQL's
// DDL is transactional, so a crash leaves v or the new version. Timestamps stay ISO 8601 text
// (as in SQLite) so both backends sort and print them alike.
inline const char* const kMigrations[] = {
    // 0 -> 1
    R"sql(
CREATE TABLE IF NOT EXISTS units (
  serial          TEXT PRIMARY KEY CHECK (serial <> ''),
  first_seen_utc  TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS runs (
  run_id            TEXT PRIMARY KEY CHECK (run_id <> ''),
  unit              TEXT NOT NULL REFERENCES units(serial),
  procedure         TEXT NOT NULL,
  procedure_hash    TEXT NOT NULL,
  started_utc       TEXT NOT NULL,
  ended_utc         TEXT,
  outcome           TEXT NOT NULL,
  run_dir           TEXT NOT NULL,
  emulated          BOOLEAN NOT NULL,
  stand             TEXT NOT NULL DEFAULT '',
  software_version  TEXT NOT NULL,
  resumes           BIGINT NOT NULL DEFAULT 0,
  pid               BIGINT NOT NULL DEFAULT 0,
  host              TEXT NOT NULL DEFAULT ''
);
CREATE INDEX IF NOT EXISTS runs_by_unit ON runs(unit, started_utc);
CREATE TABLE IF NOT EXISTS calibrations (
  id                     BIGSERIAL PRIMARY KEY,
  unit                   TEXT NOT NULL REFERENCES units(serial),
  source                 TEXT NOT NULL CHECK (source IN ('run', 'import')),
  run_id                 TEXT REFERENCES runs(run_id),
  source_ref             TEXT NOT NULL,
  label                  TEXT NOT NULL DEFAULT '',
  date_utc               TEXT NOT NULL,
  recorded_utc           TEXT NOT NULL,
  method                 TEXT NOT NULL,
  coefficients_json      TEXT NOT NULL CHECK ((coefficients_json::jsonb) IS NOT NULL),
  pitch_mean_abs_arcsec  DOUBLE PRECISION,
  pitch_sd_arcsec        DOUBLE PRECISION,
  pitch_max_abs_arcsec   DOUBLE PRECISION,
  pitch_rms_arcsec       DOUBLE PRECISION,
  pitch_points           BIGINT,
  pitch_range_lo_deg     DOUBLE PRECISION,
  pitch_range_hi_deg     DOUBLE PRECISION,
  yaw_mean_abs_arcsec    DOUBLE PRECISION,
  yaw_sd_arcsec          DOUBLE PRECISION,
  yaw_max_abs_arcsec     DOUBLE PRECISION,
  yaw_rms_arcsec         DOUBLE PRECISION,
  yaw_points             BIGINT,
  yaw_range_lo_deg       DOUBLE PRECISION,
  yaw_range_hi_deg       DOUBLE PRECISION,
  CHECK ((source = 'run') = (run_id IS NOT NULL))
);
CREATE INDEX IF NOT EXISTS calibrations_by_unit ON calibrations(unit, date_utc, id);
CREATE TABLE IF NOT EXISTS acceptances (
  id                BIGSERIAL PRIMARY KEY,
  unit              TEXT NOT NULL REFERENCES units(serial),
  run_id            TEXT REFERENCES runs(run_id),
  passed            BOOLEAN NOT NULL,
  date_utc          TEXT NOT NULL,
  recorded_utc      TEXT NOT NULL,
  certificate_json  TEXT NOT NULL CHECK ((certificate_json::jsonb) IS NOT NULL)
);
CREATE INDEX IF NOT EXISTS acceptances_by_unit ON acceptances(unit, date_utc, id);
)sql",
    // 1 -> 2: every record names the stand and host that wrote it (a fleet shares one catalogue).
    R"sql(
ALTER TABLE calibrations ADD COLUMN IF NOT EXISTS stand TEXT NOT NULL DEFAULT '';
ALTER TABLE calibrations ADD COLUMN IF NOT EXISTS host TEXT NOT NULL DEFAULT '';
ALTER TABLE acceptances ADD COLUMN IF NOT EXISTS stand TEXT NOT NULL DEFAULT '';
ALTER TABLE acceptances ADD COLUMN IF NOT EXISTS host TEXT NOT NULL DEFAULT '';
CREATE INDEX IF NOT EXISTS runs_by_stand ON runs(stand, started_utc);
)sql",
};

}  // namespace fpss::postgres_schema
