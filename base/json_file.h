// The one reader of JSON files (coefficient files, imports, truths, the run folder's own): limits
// on size and nesting depth, duplicate keys refused, every error an InputError naming the file,
// line, column and key. The limits are documented in docs/formats.md ("Limits").
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "base/text_file.h"

namespace fpss {

// Deepest nesting of arrays and objects taken (a coefficient file needs 2).
inline constexpr int kMaxJsonDepth = 64;

// Parses `text`; InputError "<origin>:<line>:<col>: ..." on a syntax error, a number beyond a double
// (1e400), nesting deeper than max_depth or a key given twice in one object (naming the key).
nlohmann::json parse_json_text(std::string_view text, const std::string& origin, int max_depth = kMaxJsonDepth);

// read_text_file (regular file, at most max_bytes) then parse_json_text: the one reader of a JSON
// file, outside files (coefficients, imports, truths) and the stand's own (run.json,
// calibration.json, acceptance.json) alike. `what` names the file in errors ("run file").
nlohmann::json read_json_file(const std::filesystem::path& path, std::string_view what = "JSON file",
                              std::uintmax_t max_bytes = kMaxConfigFileBytes);

}  // namespace fpss
