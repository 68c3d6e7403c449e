// Test helper for the file:line:column diagnostics of procedure and stand files.
#pragma once
#include <string>

#include "procedures/yaml_diag.h"

namespace fpss::test {

// Whether d holds an error at line:col whose message contains part.
inline bool has_error(const Diagnostics& d, int line, int col, const std::string& part) {
  for (const auto& e : d.all()) {
    if (e.mark.line == line && e.mark.column == col && e.message.find(part) != std::string::npos) return true;
  }
  return false;
}

}  // namespace fpss::test
