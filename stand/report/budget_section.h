// The report's uncertainty-budget section: calibration.json's GUM budget of each axis, as written there.
#pragma once
#include <string>

#include "stand/report/report.h"

namespace fpss {

// Appends the section to h; nothing when calibration.json has no budget (an older file).
void budget_section(std::string& h, const ReportInput& in);

}  // namespace fpss
