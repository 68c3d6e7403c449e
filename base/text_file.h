// Whole text files: read with limits and an error naming the file; written atomically through an
// unpredictable temporary file in the same folder (never following a planted symlink), then renamed.
// The limits are documented in docs/formats.md ("Limits").
#pragma once
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

#include "base/unique_fd.h"

namespace fpss {

// Largest text file any reader takes (a samples CSV of 2 million rows is about 150 MB).
inline constexpr std::uintmax_t kMaxTextFileBytes = std::uintmax_t{1} << 30;  // 1 GiB
// Largest coefficient, procedure, stand, bench or limits file (JSON, YAML).
inline constexpr std::uintmax_t kMaxConfigFileBytes = std::uintmax_t{16} << 20;  // 16 MiB

// The file's bytes. InputError (exit 2) naming the file when it cannot be opened ("<path>: cannot
// open <what>: <why>"), is not a regular file (a folder, /dev/zero, a FIFO: checked before any
// read, so nothing blocks or grows without bound), or is larger than max_bytes.
// The checks every reader of an outside file makes before opening it: it exists, is a regular file
// (not a folder, FIFO or device, which would hang or exhaust memory) and is at most max_bytes.
// InputError naming the path otherwise.
void check_input_file(const std::filesystem::path& path, std::string_view what, std::uintmax_t max_bytes);
std::string read_text_file(const std::filesystem::path& path, std::string_view what,
                           std::uintmax_t max_bytes = kMaxTextFileBytes);

// Checks, before any work, that `out` can be written as a new file and is none of `inputs`:
// InputError (exit 2) when out is a folder, its folder is missing, not a folder or not writable
// (read-only file system included), or out is the same file as an input (same device and inode,
// however it is spelled: relative, ../, a symlink or a hard link). `option` names the option in
// the message ("--out"). Inputs that do not exist are ignored.
void check_output_path(const std::filesystem::path& out, const std::vector<std::filesystem::path>& inputs = {},
                       std::string_view option = "--out");

// A file written whole or not at all: the bytes go to a temporary file created in the target's
// folder with O_CREAT|O_EXCL|O_NOFOLLOW|O_CLOEXEC under an unpredictable name
// (".<name>.tmp-<16 random hex digits>"), so a symlink planted there is never followed and no other
// writer shares it. commit() syncs it, renames it over the target and syncs the folder. Destroyed
// without commit() (an exception, a full disk), the temporary file is removed and the target is
// left as it was. Errors are std::runtime_error naming the file (exit 1).
class AtomicFile {
 public:
  explicit AtomicFile(const std::filesystem::path& path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  void write(std::string_view bytes);
  void commit();
  const std::filesystem::path& temp_path() const { return tmp_; }
  const std::filesystem::path& path() const { return path_; }

 private:
  void discard() noexcept;
  std::filesystem::path path_, tmp_;
  UniqueFd fd_;
  bool committed_ = false;
};

// Writes `text` with an AtomicFile: a crash or a full disk leaves the old file or the new one,
// never half of one, and no temporary file.
void write_text_atomic(const std::filesystem::path& path, const std::string& text);

}  // namespace fpss
