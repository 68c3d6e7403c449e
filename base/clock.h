// The wall clock as the files show it: now in ISO 8601 UTC (run.json, the journal, the catalogue, reports).
#pragma once
#include <string>

namespace fpss {

// Now as ISO 8601 UTC, 2024-05-01T12:00:00Z.
std::string utc_now_iso();

}  // namespace fpss
