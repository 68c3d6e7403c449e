// Test helper for the file:line:column diagnostics of procedure and stand files.
#pragma once
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
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

// A file a test parses, with the errors expected in it: each marked on its own line by a comment
// "# error@COL: TEXT" (several may follow one another), as clang's -verify marks them, so an
// expectation stays next to the line it is about instead of naming a line number counted by hand.
struct AnnotatedFile {
  std::string name, text;  // name: the file's name, the origin its diagnostics give
  std::vector<ExpectedError> errors;
};

inline AnnotatedFile annotated_file(const std::filesystem::path& path) {
  static const std::string kMark = "# error@";
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  AnnotatedFile f{path.filename().string(), {}, {}};
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    f.text += line + "\n";
    for (size_t at = line.find(kMark); at != std::string::npos;) {
      const size_t col_at = at + kMark.size(), colon = line.find(": ", col_at);
      if (colon == std::string::npos) throw std::runtime_error(path.string() + ": a mark without \": TEXT\"");
      const size_t next = line.find("  " + kMark, colon);
      const size_t end = next == std::string::npos ? line.size() : next;
      f.errors.push_back({n, std::stoi(line.substr(col_at, colon - col_at)), line.substr(colon + 2, end - colon - 2)});
      at = next == std::string::npos ? next : next + 2;
    }
  }
  // A file that expects nothing would make its test assert nothing.
  if (f.errors.empty()) throw std::runtime_error(path.string() + ": no \"# error@COL: TEXT\" marks");
  return f;
}

}  // namespace fpss::test
