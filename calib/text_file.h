// Whole text files: read with an error naming the file, written atomically (temporary file, fsync, rename).
#pragma once
#include <filesystem>
#include <string>
#include <string_view>

namespace fpss {

// The file's bytes; InputError "<path>: cannot open <what>" (e.g. what = "stand file") when it cannot be opened.
std::string read_text_file(const std::filesystem::path& path, std::string_view what);

// Writes `text` to <path>.tmp, syncs it, renames it over `path` and syncs the folder: a crash
// leaves the old file or the new one, never half of one. std::runtime_error naming the file.
void write_text_atomic(const std::filesystem::path& path, const std::string& text);

}  // namespace fpss
