// The catalogue's migrations, written once: where SQLite and PostgreSQL spell a type or a clause
// differently, the text has a placeholder that each dialect's spelling fills in.
#include "stand/catalogue/schema.h"

#include <fmt/format.h>

#include <iterator>
#include <stdexcept>
#include <string_view>

#include "stand/catalogue/catalogue.h"

namespace fpss::schema {
namespace {

// kMigrations[v] takes a catalogue from schema version v to v + 1; a later version appends a step
// here (and bumps Catalogue::kSchemaVersion). Timestamps are ISO 8601 text in both dialects, so
// both backends sort and print them alike.
const char* const kMigrations[] = {
    // 0 -> 1
    R"sql(
CREATE TABLE IF NOT EXISTS units (
  serial          TEXT {primary_key} CHECK (serial <> ''),
  first_seen_utc  TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS runs (
  run_id            TEXT {primary_key} CHECK (run_id <> ''),
  unit              TEXT NOT NULL REFERENCES units(serial),
  procedure         TEXT NOT NULL,
  procedure_hash    TEXT NOT NULL,
  started_utc       TEXT NOT NULL,
  ended_utc         TEXT,
  outcome           TEXT NOT NULL,
  run_dir           TEXT NOT NULL,
  emulated          {flag emulated},
  stand             TEXT NOT NULL DEFAULT '',
  software_version  TEXT NOT NULL,
  resumes           {integer} NOT NULL DEFAULT 0,
  pid               {integer} NOT NULL DEFAULT 0,
  host              TEXT NOT NULL DEFAULT ''
);
CREATE INDEX IF NOT EXISTS runs_by_unit ON runs(unit, started_utc);
CREATE TABLE IF NOT EXISTS calibrations (
  id                     {row_id},
  unit                   TEXT NOT NULL REFERENCES units(serial),
  source                 TEXT NOT NULL CHECK (source IN ('run', 'import')),
  run_id                 TEXT REFERENCES runs(run_id),
  source_ref             TEXT NOT NULL,
  label                  TEXT NOT NULL DEFAULT '',
  date_utc               TEXT NOT NULL,
  recorded_utc           TEXT NOT NULL,
  method                 TEXT NOT NULL,
  coefficients_json      TEXT NOT NULL CHECK ({json coefficients_json}),
  pitch_mean_abs_arcsec  {real},
  pitch_sd_arcsec        {real},
  pitch_max_abs_arcsec   {real},
  pitch_rms_arcsec       {real},
  pitch_points           {integer},
  pitch_range_lo_deg     {real},
  pitch_range_hi_deg     {real},
  yaw_mean_abs_arcsec    {real},
  yaw_sd_arcsec          {real},
  yaw_max_abs_arcsec     {real},
  yaw_rms_arcsec         {real},
  yaw_points             {integer},
  yaw_range_lo_deg       {real},
  yaw_range_hi_deg       {real},
  CHECK ((source = 'run') = (run_id IS NOT NULL))
);
CREATE INDEX IF NOT EXISTS calibrations_by_unit ON calibrations(unit, date_utc, id);
CREATE TABLE IF NOT EXISTS acceptances (
  id                {row_id},
  unit              TEXT NOT NULL REFERENCES units(serial),
  run_id            TEXT REFERENCES runs(run_id),
  passed            {flag passed},
  date_utc          TEXT NOT NULL,
  recorded_utc      TEXT NOT NULL,
  certificate_json  TEXT NOT NULL CHECK ({json certificate_json})
);
CREATE INDEX IF NOT EXISTS acceptances_by_unit ON acceptances(unit, date_utc, id);
)sql",
    // 1 -> 2: every record names the stand and host that wrote it (a fleet shares one catalogue).
    R"sql(
ALTER TABLE calibrations {add_column} stand TEXT NOT NULL DEFAULT '';
ALTER TABLE calibrations {add_column} host TEXT NOT NULL DEFAULT '';
ALTER TABLE acceptances {add_column} stand TEXT NOT NULL DEFAULT '';
ALTER TABLE acceptances {add_column} host TEXT NOT NULL DEFAULT '';
CREATE INDEX IF NOT EXISTS runs_by_stand ON runs(stand, started_utc);
)sql",
    // 2 -> 3: every run, calibration and acceptance names its operator (run.json's `operator`; '' when
    // none was named), so that operators can be a measurement-system study's appraisers.
    R"sql(
ALTER TABLE runs {add_column} operator TEXT NOT NULL DEFAULT '';
ALTER TABLE calibrations {add_column} operator TEXT NOT NULL DEFAULT '';
ALTER TABLE acceptances {add_column} operator TEXT NOT NULL DEFAULT '';
)sql",
};
static_assert(std::size(kMigrations) == Catalogue::kSchemaVersion);

// What the placeholders of kMigrations stand for in each dialect: `{name}` for the spelling,
// `{name column}` for the spelling with the column's name in place of its `{column}`.
struct Spelling {
  const char* name;
  const char* sqlite;
  const char* postgres;
};
const Spelling kSpellings[] = {
    // SQLite lets a PRIMARY KEY that is not an INTEGER hold NULL unless it says otherwise.
    {"primary_key", "PRIMARY KEY NOT NULL", "PRIMARY KEY"},
    // AUTOINCREMENT: SQLite never hands an id out again, as a sequence never does.
    {"row_id", "INTEGER PRIMARY KEY AUTOINCREMENT", "BIGSERIAL PRIMARY KEY"},
    // 64 bits in both, so a copy between the backends loses nothing.
    {"integer", "INTEGER", "BIGINT"},
    {"real", "REAL", "DOUBLE PRECISION"},
    // SQLite has no boolean type.
    {"flag", "INTEGER NOT NULL CHECK ({column} IN (0, 1))", "BOOLEAN NOT NULL"},
    // PostgreSQL's cast fails on text that is not JSON.
    {"json", "json_valid({column})", "({column}::jsonb) IS NOT NULL"},
    // SQLite's ADD COLUMN has no IF NOT EXISTS; there user_version alone says whether a step ran.
    {"add_column", "ADD COLUMN", "ADD COLUMN IF NOT EXISTS"},
};

// What `placeholder` ("name" or "name column", between the braces) stands for in `dialect`.
std::string spelled(std::string_view placeholder, Dialect dialect) {
  const size_t space = placeholder.find(' ');
  const std::string_view name = placeholder.substr(0, space);
  for (const Spelling& s : kSpellings) {
    if (name != s.name) continue;
    std::string text = dialect == Dialect::sqlite ? s.sqlite : s.postgres;
    const size_t column = text.find("{column}");
    if (space != std::string_view::npos && column != std::string::npos) {
      text.replace(column, 8, placeholder.substr(space + 1));
    }
    return text;
  }
  throw std::logic_error(fmt::format("catalogue schema: no spelling of {{{}}}", placeholder));
}

}  // namespace

std::string migration(int step, Dialect dialect) {
  const std::string_view text = kMigrations[step];
  std::string sql;
  size_t at = 0;
  for (size_t open; (open = text.find('{', at)) != std::string_view::npos;) {
    const size_t close = text.find('}', open);
    if (close == std::string_view::npos) throw std::logic_error("catalogue schema: a '{' without its '}'");
    sql.append(text.substr(at, open - at));
    sql += spelled(text.substr(open + 1, close - open - 1), dialect);
    at = close + 1;
  }
  sql.append(text.substr(at));
  return sql;
}

}  // namespace fpss::schema
