// "this file is a samples CSV; calibrate takes it with --data": what kind of file a path holds (by its
// first bytes), and the hint an input error gets when a file was given to the wrong option.
#pragma once
#include <filesystem>
#include <string>

#include <CLI/CLI.hpp>

namespace fpss::cli {

enum class FileKind { unknown, samples, coefficients, procedure, stand, bench, limits, run_folder };

// Looks at a regular file's first 16 KiB (never opens a FIFO or a device) or a folder's run.json.
FileKind sniff_file_kind(const std::filesystem::path& path);

// `opt` of `sub` takes a file of this kind; `path` (the option's value) must outlive the parse.
void expect_file(CLI::App* sub, CLI::Option* opt, const std::string& path, FileKind kind);

// For an input error's message: "hint: ..." when it names a given file of a kind other than its
// option's and there is an option (or command) that takes that kind; "" otherwise.
std::string file_hint(const std::string& message);

}  // namespace fpss::cli
