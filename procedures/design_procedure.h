// An experiment design (calib/design.h) as the files and JSON `fpss-stand design` writes.
#pragma once
#include <string>

#include <nlohmann/json.hpp>

#include "calib/design.h"

namespace fpss {

// home; one null_offset_grid with the design's offsets listed in recording order (pitch, then yaw),
// its frames per dwell and settle; calibrate by the differences method; the paper's Table 1 check.
// The header comment records the target, the prediction and the inputs it rests on.
std::string design_procedure_text(const ExperimentDesign& d, const DesignInputs& in, const std::string& name);

// Where the design's inputs came from, in words, for the JSON's `inputs` block.
struct DesignSources {
  std::string bench, count_noise, prior;
};

// The design as JSON (`design --json`, and Python's `design()`): the prediction, the offsets in
// recording order, the inputs with their sources, and the paper's grid (procedures/discrete_grid.yaml)
// on the same bench for comparison.
nlohmann::ordered_json design_report_json(const ExperimentDesign& d, const DesignInputs& in,
                                          const DesignSources& src);

}  // namespace fpss
