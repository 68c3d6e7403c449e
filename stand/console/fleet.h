// The console's fleet page data: every stand's last run, each unit's latest verdict, the last measurement-system analysis.
#pragma once
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "stand/console/catalogue_pool.h"

namespace fpss::console {

// GET /api/fleet (docs/console.md): from the console's catalogue (the fleet's shared one with
// serve --catalogue) and the newest `fpss-stand msa/1` file in RUNS_DIR/msa/. Bounded: the last
// 5,000 runs, 1,000 units.
nlohmann::json fleet_json(CataloguePool& catalogue);

}  // namespace fpss::console
