#include "base/text_file.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <random>
#include <stdexcept>

#include "base/errors.h"
#include "base/unique_fd.h"

namespace fpss {

namespace fs = std::filesystem;

namespace {

const char* kind_of(mode_t m) {
  if (S_ISDIR(m)) return "a folder";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISCHR(m)) return "a character device";
  if (S_ISBLK(m)) return "a block device";
  if (S_ISSOCK(m)) return "a socket";
  return "not a plain file";
}

std::string random_hex(size_t digits) {
  unsigned char b[16] = {};
  const size_t n = (digits + 1) / 2;
  if (::getrandom(b, n, 0) != static_cast<ssize_t>(n)) {
    std::random_device rd;  // getrandom unavailable: the library's own entropy source
    for (size_t i = 0; i < n; ++i) b[i] = static_cast<unsigned char>(rd());
  }
  std::string s;
  for (size_t i = 0; i < n; ++i) s += fmt::format("{:02x}", b[i]);
  s.resize(digits);
  return s;
}

}  // namespace

void check_input_file(const fs::path& path, std::string_view what, std::uintmax_t max_bytes) {
  struct stat st{};
  if (::stat(path.c_str(), &st) != 0) {
    throw InputError(fmt::format("{}: cannot open {}: {}", path.string(), what, std::strerror(errno)));
  }
  if (!S_ISREG(st.st_mode)) {
    throw InputError(fmt::format("{}: not a regular file ({}); expected the {}", path.string(), kind_of(st.st_mode), what));
  }
  if (static_cast<std::uintmax_t>(st.st_size) > max_bytes) {
    throw InputError(fmt::format("{}: {} bytes, more than the {} bytes a {} may have (docs/formats.md, Limits)",
                                 path.string(), st.st_size, max_bytes, what));
  }
}

std::string read_text_file(const fs::path& path, std::string_view what, std::uintmax_t max_bytes) {
  check_input_file(path, what, max_bytes);
  struct stat st{};
  const UniqueFd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOCTTY | O_NONBLOCK));
  if (!fd) throw InputError(fmt::format("{}: cannot open {}: {}", path.string(), what, std::strerror(errno)));
  // Checked again on the open descriptor: the path may have been swapped since stat().
  if (::fstat(fd.get(), &st) != 0 || !S_ISREG(st.st_mode)) {
    throw InputError(fmt::format("{}: not a regular file; expected the {}", path.string(), what));
  }
  std::string text;
  text.resize(static_cast<size_t>(st.st_size));
  size_t got = 0;
  for (;;) {
    if (got == text.size()) {
      if (text.size() > max_bytes) break;
      text.resize(std::min<std::uintmax_t>(text.size() + 65536, max_bytes + 1));  // the file grew meanwhile
    }
    const ssize_t n = ::read(fd.get(), text.data() + got, text.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const std::string why = std::strerror(errno);
      throw InputError(fmt::format("{}: cannot read {}: {}", path.string(), what, why));
    }
    if (n == 0) break;
    got += static_cast<size_t>(n);
  }
  if (got > max_bytes) {
    throw InputError(fmt::format("{}: more than the {} bytes a {} may have (docs/formats.md, Limits)", path.string(),
                                 max_bytes, what));
  }
  text.resize(got);
  return text;
}

void check_output_path(const fs::path& out, const std::vector<fs::path>& inputs, std::string_view option) {
  if (out.empty()) throw InputError(fmt::format("{}: the output path is empty", option));
  struct stat st{};
  const bool exists = ::stat(out.c_str(), &st) == 0;
  if (exists && S_ISDIR(st.st_mode)) {
    throw InputError(fmt::format("{} {}: is a folder; expected a file name", option, out.string()));
  }
  const fs::path dir = out.parent_path().empty() ? fs::path(".") : out.parent_path();
  struct stat dst{};
  if (::stat(dir.c_str(), &dst) != 0) {
    throw InputError(fmt::format("{} {}: its folder {} does not exist ({})", option, out.string(), dir.string(),
                                 std::strerror(errno)));
  }
  if (!S_ISDIR(dst.st_mode)) {
    throw InputError(fmt::format("{} {}: {} is not a folder", option, out.string(), dir.string()));
  }
  // access() reports EROFS for a read-only file system even to root.
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    throw InputError(fmt::format("{} {}: its folder {} is not writable ({})", option, out.string(), dir.string(),
                                 std::strerror(errno)));
  }
  if (!exists) return;
  for (const auto& in : inputs) {
    struct stat ist{};
    if (in.empty() || ::stat(in.c_str(), &ist) != 0) continue;
    if (ist.st_dev == st.st_dev && ist.st_ino == st.st_ino) {
      throw InputError(fmt::format("{} {}: is the same file as the input {}; writing it would destroy the input",
                                   option, out.string(), in.string()));
    }
  }
}

AtomicFile::AtomicFile(const fs::path& path) : path_(path) {
  const fs::path dir = path.parent_path();
  const std::string name = path.filename().string();
  for (int attempt = 0; attempt < 16; ++attempt) {
    tmp_ = dir / ("." + name + ".tmp-" + random_hex(16));
    fd_.reset(::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644));
    if (fd_) return;
    if (errno != EEXIST) break;
  }
  const std::string why = std::strerror(errno);
  throw std::runtime_error(fmt::format("{}: cannot write (temporary file {}): {}", path.string(), tmp_.string(), why));
}

AtomicFile::~AtomicFile() { discard(); }

void AtomicFile::discard() noexcept {
  fd_.reset();
  if (!committed_ && !tmp_.empty()) {
    ::unlink(tmp_.c_str());
    tmp_.clear();
  }
}

void AtomicFile::write(std::string_view bytes) {
  if (!fd_) throw std::logic_error("AtomicFile::write after commit or failure");
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_.get(), bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = n < 0 ? std::strerror(errno) : "nothing written";
      discard();
      throw std::runtime_error(fmt::format("{}: write failed: {} (nothing was written there)", path_.string(), why));
    }
    done += static_cast<size_t>(n);
  }
}

void AtomicFile::commit() {
  if (!fd_) throw std::logic_error("AtomicFile::commit twice or after a failure");
  // A full disk may show only at fsync or close (delayed allocation, NFS): both are checked.
  if (::fsync(fd_.get()) != 0) {
    const std::string why = std::strerror(errno);
    discard();
    throw std::runtime_error(fmt::format("{}: cannot sync: {} (nothing was written there)", path_.string(), why));
  }
  const int rc = ::close(fd_.release());  // its result counts: checked here, not in reset()
  if (rc != 0) {
    const std::string why = std::strerror(errno);
    discard();
    throw std::runtime_error(fmt::format("{}: cannot sync: {} (nothing was written there)", path_.string(), why));
  }
  if (::rename(tmp_.c_str(), path_.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    discard();
    throw std::runtime_error(fmt::format("{}: cannot rename the temporary file over it: {}", path_.string(), why));
  }
  committed_ = true;
  // The rename itself is durable only once the folder is synced.
  const fs::path dir = path_.parent_path().empty() ? fs::path(".") : path_.parent_path();
  if (const UniqueFd dfd(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)); dfd) ::fsync(dfd.get());
}

void write_text_atomic(const fs::path& path, const std::string& text) {
  AtomicFile f(path);
  f.write(text);
  f.commit();
}

}  // namespace fpss
