// run.json's record of one session at its end: the engine's timings and the sensor link's counters.
#pragma once
#include <nlohmann/json.hpp>

#include "drivers/sensor.h"
#include "procedures/engine.h"
#include "procedures/plan.h"
#include "stand/catalogue/run_file.h"

namespace fpss {

// Ends `s` (a run.json `sessions` entry): outcome, reason, points, the engine's timings against the
// plan's physical minimum and estimate, and the counters of `sensor` (the first unit's) when given.
void end_session_record(RunFileSession& s, const std::string& end_utc, const EngineResult& er, const EngineStats& st,
                        const Plan& plan, const Sensor* sensor);

}  // namespace fpss
