// GAP.html: the diagnosis as one self-contained page (the verdict first, then the limits, the
// causes, where the gap lies, every candidate, and the figures drawn by gnuplot when installed).
#pragma once
#include <string>

#include "calib/diagnosis/diagnosis.h"

namespace fpss {

// Writes the page atomically. Without gnuplot (not installed, or $FPSS_GNUPLOT pointing nowhere)
// the page says so and keeps every table.
void write_diagnosis_page(const std::string& html_path, const Diagnosis& d, const DiagnosisFigures& figures);

}  // namespace fpss
