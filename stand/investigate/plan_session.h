// What a procedure would record on an in-process bench (no wire, no engine): the planned run a
// follow-up design predicts with, and the confusable-case benchmark's runs.
#pragma once
#include <vector>

#include "calib/samples.h"
#include "fixtures/bench.h"
#include "fixtures/recording.h"
#include "procedures/plan.h"
#include "procedures/settings.h"

namespace fpss {

// The plan's moves, settles, dwells and slews in bench terms (as the engine does them: a dwell
// moves to its point, settles, then samples at the stand's rate; a slew moves to its start,
// settles, then records every leg of its segment in one step). Home is a move to (0, 0).
std::vector<SessionOp> session_ops(const Plan& plan, const EngineSettings& settings);

// The procedure expanded for the stand and run on a fresh bench (its noise, effects and seed):
// samples in the contract with temperature_c and time_since_move_s. `start_s`: the bench's clock
// when the run starts (its environment, temperature and drift, has run that long: a later run on
// the same bench); the recorded time_s runs on that clock. Throws InputError when the procedure
// does not expand on the stand.
SampleTable simulate_procedure(const Procedure& procedure, const EngineSettings& settings, const BenchConfig& bench,
                               double start_s = 0);
// The same for a plan already expanded for the stand (its origin: the recording's).
SampleTable simulate_plan(const Plan& plan, const EngineSettings& settings, const BenchConfig& bench,
                          double start_s = 0, const std::string& origin = {});

}  // namespace fpss
