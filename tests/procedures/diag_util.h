// Test helper for the file:line:column diagnostics of procedure and stand files.
#pragma once
#include <gtest/gtest.h>

#include <initializer_list>
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

// An error a test expects: where, and a part of its message.
struct ExpectedError {
  int line, col;
  std::string part;
};

// Whether d holds each of the expected errors; on failure, which are missing and all d holds.
inline ::testing::AssertionResult has_errors(const Diagnostics& d, std::initializer_list<ExpectedError> expected) {
  std::string missing;
  for (const auto& e : expected) {
    if (has_error(d, e.line, e.col, e.part)) continue;
    missing += "\n  " + std::to_string(e.line) + ":" + std::to_string(e.col) + ": " + e.part;
  }
  if (missing.empty()) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "missing:" << missing << "\nin:\n" << d.text();
}

// The same, and no other errors.
inline ::testing::AssertionResult has_exactly(const Diagnostics& d, std::initializer_list<ExpectedError> expected) {
  auto each = has_errors(d, expected);
  if (!each) return each;
  if (d.size() == expected.size()) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << d.size() << " errors where " << expected.size() << " are expected:\n"
                                       << d.text();
}

}  // namespace fpss::test
