// The procedure file of an experiment design (calib/design.h): what `fpss-stand design --out` writes.
#pragma once
#include <string>

#include "calib/design.h"

namespace fpss {

// home; one null_offset_grid with the design's offsets listed in recording order (pitch, then yaw),
// its frames per dwell and settle; calibrate by the differences method; the paper's Table 1 check.
// The header comment records the target, the prediction and the inputs it rests on.
std::string design_procedure_text(const ExperimentDesign& d, const DesignInputs& in, const std::string& name);

}  // namespace fpss
