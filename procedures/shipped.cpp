// Where the shipped procedures live: its own file, so that only this object depends on the checkout's path.
#include <cstdlib>

#include "procedures/procedure.h"

namespace fpss {

std::filesystem::path shipped_procedures_dir() {
  if (const char* env = std::getenv("FPSS_PROCEDURES_DIR"); env && *env) return env;
  return std::filesystem::path(FPSS_SOURCE_DIR) / "procedures";
}

}  // namespace fpss
