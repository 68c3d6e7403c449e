// Copying one catalogue into another (SQLite to PostgreSQL and back): `fpss-stand catalogue copy`.
#pragma once
#include "stand/catalogue/catalogue.h"

namespace fpss {

struct CopyReport {
  int units_added = 0, runs_added = 0, calibrations_added = 0, acceptances_added = 0;
  int runs_seen = 0, calibrations_seen = 0, acceptances_seen = 0;
};

// Every unit, run (as recorded: start, end, outcome, stand, host, pid), calibration and acceptance of
// `from` that `to` lacks. Idempotent: a run is known by its id, a calibration by its run (or import
// date) and coefficients, an acceptance by its run, date and verdict. Ids of calibrations and
// acceptances are the target's own; recorded_utc is when the copy entered them.
CopyReport copy_catalogue(const Catalogue& from, Catalogue& to);

}  // namespace fpss
