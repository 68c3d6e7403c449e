// Records the catalogue tests share: a run start of the discrete grid, emulated.
#pragma once
#include <string>

#include "stand/catalogue/catalogue.h"

namespace fpss::test {

inline RunStart make_run(const std::string& id, const std::string& unit, const std::string& started = "",
                         const std::string& stand = "") {
  RunStart r;
  r.run_id = id;
  r.unit = unit;
  r.procedure = "discrete_grid";
  r.procedure_hash = "sha256:0123abcd";
  r.started_utc = started;
  r.run_dir = "runs/" + id;
  r.emulated = true;
  r.stand = stand;
  return r;
}

}  // namespace fpss::test
