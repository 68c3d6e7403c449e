// Test helpers for the procedure engine and `fpss-stand run`: run folders and their files (the rest is tests/support).
#pragma once
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "tests/support/test_support.h"

namespace fpss::test {

namespace fs = std::filesystem;

// Run folders under a runs dir (stand.db and hidden files aside).
inline std::vector<fs::path> run_dirs(const fs::path& runs) {
  std::vector<fs::path> out;
  if (!fs::exists(runs)) return out;
  for (const auto& e : fs::directory_iterator(runs)) {
    if (e.is_directory() && e.path().filename().string()[0] != '.') out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

inline size_t count_lines(const fs::path& p) {
  std::ifstream in(p);
  size_t n = 0;
  std::string l;
  while (std::getline(in, l)) if (!l.empty()) ++n;
  return n;
}

// Points journaled so far by the first run folder under runs (0 before there is one).
inline size_t journaled_points(const fs::path& runs) {
  const auto d = run_dirs(runs);
  return d.empty() ? 0 : count_lines(d.front() / "points.jsonl");
}

}  // namespace fpss::test
