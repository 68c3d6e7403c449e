// A run's sensor units: connecting each (one that fails is dropped when there are several), their run.json entries, outcomes and relative poses.
#pragma once
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <spdlog/logger.h>

#include "calib/calibrator.h"
#include "calib/samples.h"
#include "drivers/sensor.h"
#include "procedures/engine.h"
#include "procedures/procedure.h"
#include "procedures/recorder.h"
#include "stand/catalogue/run_file.h"
#include "stand/config/stand_config.h"

namespace fpss {

// One sensor unit of the run: its device, its recording and its fits (several units: each its own).
struct SessionUnit {
  StandUnit cfg;
  std::unique_ptr<Sensor> sensor;
  std::string id_reply, serial;
  std::optional<UnitLoss> loss;  // dropped at the connection or during the run
  SampleTable recorded;          // every row so far, old (a resume) and new: what calibrate steps fit
  std::optional<CalibrationReport> cal;
  std::optional<std::filesystem::path> calibration;  // its latest calibration file
  std::filesystem::path dir;                         // the run folder (one unit) or RUN_DIR/units/<SERIAL>
};

// Connects every unit of the stand and checks its serial. One unit: InputError (a wrong serial) and
// DeviceError go up. Several: a unit that cannot be reached or reports another serial is dropped
// (`loss`, logged) and the others go on; InputError when none is left or two report one serial.
std::vector<SessionUnit> connect_units(const StandConfig& stand, spdlog::logger& log);
// The units not lost before the run, as the engine reads them (each with its own sensor options).
std::vector<EngineUnit> engine_units(const std::vector<SessionUnit>& units);
// The run's name for its units: the serial, or the serials joined with '+'.
std::string units_name(const std::vector<SessionUnit>& units);

// The units' serials, for the recorder (which lays out their folders).
std::vector<std::string> unit_serials(const std::vector<SessionUnit>& units);
// Each unit's folder (where the recorder keeps its samples.csv: the run folder, or
// RUN_DIR/units/<SERIAL> for several) and its recording so far (a resume's, read once) with the
// recorder's columns.
void open_recordings(std::vector<SessionUnit>& units, const RunRecorder& rec);
// A calibrate step's options for one unit (its serial and mount; the stand's reference, which the
// engine already applied to the rows, so the fit carries its u).
CalibrationOptions calibration_options(const CalibrateStep& step, const SessionUnit& unit, const EngineSettings& bench);

// run.json's `units` at the start: each unit's serial, answer, endpoint, samples file and a loss
// found at the connection.
std::vector<RunFileUnit> unit_entries(const std::vector<SessionUnit>& units, const RunRecorder& rec,
                                      const std::filesystem::path& run_dir);
// At the end: each entry's outcome (the run's, unless the unit was lost), loss and calibration.
void record_unit_outcomes(const std::vector<SessionUnit>& units, RunOutcome outcome, const std::filesystem::path& run_dir,
                          RunFile& run);
// Each calibrated unit's boresight and roll relative to the first calibrated one, into run.json's
// entries (calib/unit_alignment.h).
void relate_units(const std::vector<SessionUnit>& units, RunFile& run, spdlog::logger& log);

}  // namespace fpss
