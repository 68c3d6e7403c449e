// What both catalogue backends share about records: the rules a record must keep before it is
// written, and the names of the Table-1 statistic columns.
#pragma once
#include <string>

#include "stand/catalogue/catalogue.h"

namespace fpss {

// The residual statistics stored per axis, as columns `<axis>_<name>` (pitch_mean_abs_arcsec, ...).
inline constexpr const char* kStatColumns[] = {"mean_abs_arcsec", "sd_arcsec",    "max_abs_arcsec", "rms_arcsec",
                                               "points",          "range_lo_deg", "range_hi_deg"};

// InputError for an empty serial.
void require_unit(const std::string& serial);
// std::invalid_argument for a calibration no backend may store (unknown source, a run's without
// its run id, an import with one, coefficients that are not an object).
void check_calibration(const CalibrationRecord& cal);

}  // namespace fpss
