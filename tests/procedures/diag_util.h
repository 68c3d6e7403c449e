// Test helper for the file:line:column diagnostics of procedure and stand files.
#pragma once
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

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
inline ::testing::AssertionResult has_errors(const Diagnostics& d, const std::vector<ExpectedError>& expected) {
  std::string missing;
  for (const auto& e : expected) {
    if (has_error(d, e.line, e.col, e.part)) continue;
    missing += "\n  " + std::to_string(e.line) + ":" + std::to_string(e.col) + ": " + e.part;
  }
  if (missing.empty()) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "missing:" << missing << "\nin:\n" << d.text();
}

// The same, and no other errors.
inline ::testing::AssertionResult has_exactly(const Diagnostics& d, const std::vector<ExpectedError>& expected) {
  auto each = has_errors(d, expected);
  if (!each) return each;
  if (d.size() == expected.size()) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << d.size() << " errors where " << expected.size() << " are expected:\n"
                                       << d.text();
}

// One line of a file a test writes, with the errors expected on it: column and a part of the message.
struct LineExpecting {
  std::string text;
  std::vector<std::pair<int, std::string>> errors = {};
};

// A file's text and the errors expected in it, their line numbers taken from where they stand.
struct FileExpecting {
  std::string text;
  std::vector<ExpectedError> errors;
};

// The lines joined, each ending in a newline, so an expectation stays next to the line it is about
// instead of naming a line number counted by hand.
inline FileExpecting file_expecting(const std::vector<LineExpecting>& lines) {
  FileExpecting f;
  int line = 0;
  for (const auto& l : lines) {
    f.text += l.text + "\n";
    ++line;
    for (const auto& [col, part] : l.errors) f.errors.push_back({line, col, part});
  }
  return f;
}

}  // namespace fpss::test
