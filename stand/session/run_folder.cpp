#include "stand/session/run_folder.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/random.h>
#include <unistd.h>

#include <fmt/format.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <string>

#include "base/clock.h"
#include "base/errors.h"
#include "base/json_file.h"
#include "procedures/procedure.h"
#include "procedures/recorder.h"

namespace fpss {

namespace fs = std::filesystem;

fs::path canonical_run_dir(const fs::path& dir) {
  std::error_code ec;
  const fs::path c = fs::canonical(dir, ec);
  if (ec) throw InputError(fmt::format("{}: {}", dir.string(), ec.message()));
  if (!fs::is_directory(c)) throw InputError(fmt::format("{}: not a folder", dir.string()));
  return c;
}

RunFolderLock::RunFolderLock(const fs::path& run_dir) : RunFolderLock(run_dir, ".lock", "the run folder") {}

RunFolderLock::RunFolderLock(const fs::path& run_dir, const std::string& file, const std::string& what) {
  const fs::path path = run_dir / file;
  fd_.reset(::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644));
  if (!fd_) throw std::runtime_error(fmt::format("{}: cannot open: {}", path.string(), std::strerror(errno)));
  if (::flock(fd_.get(), LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    char buf[32] = {0};
    const ssize_t n = ::pread(fd_.get(), buf, sizeof buf - 1, 0);
    fd_.reset();
    if (err != EWOULDBLOCK) throw std::runtime_error(fmt::format("{}: cannot lock: {}", path.string(), std::strerror(err)));
    const std::string pid = n > 0 ? std::string(buf, static_cast<size_t>(n)) : std::string("?");
    throw RunFolderBusy(fmt::format("{}: {} is in use by another fpss-stand (pid {}); nothing was written",
                                    run_dir.string(), what, pid.substr(0, pid.find_first_of("\n"))));
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  // Without the pid the lock still holds; only a second owner's message is poorer.
  if (::ftruncate(fd_.get(), 0) == 0) (void)!::pwrite(fd_.get(), pid.data(), pid.size(), 0);
}

RunFolderLock::~RunFolderLock() = default;  // closing the descriptor releases the flock

RunInfo read_run_info(const fs::path& run_dir) {
  const fs::path path = run_dir / "run.json";
  if (!fs::exists(path)) throw InputError(fmt::format("{}: not a run folder (no run.json)", run_dir.string()));
  RunInfo info;
  info.run = read_run_file(run_dir);
  info.procedure_text = info.run.procedure.text;
  info.procedure_origin = info.run.procedure.file.value_or("procedure.yaml");
  if (sha256_hex(info.procedure_text) != info.run.procedure.sha256) {
    throw InputError(fmt::format("{}: the procedure text does not match its recorded hash", path.string()));
  }
  if (info.run.stand) {
    info.stand_text = info.run.stand->text.value_or("");
    info.stand_origin = info.run.stand->file.value_or("");
  }
  if (info.run.emulated) {
    if (!info.run.emulator) throw InputError(fmt::format("{}: key \"emulator\": missing", path.string()));
    try {
      info.emulator = EmulatorSpec::from_json(*info.run.emulator, path.string());
    } catch (const nlohmann::json::exception& e) {
      throw InputError(fmt::format("{}: emulator: {}", path.string(), e.what()));
    }
  }
  return info;
}

std::string new_run_id() {
  std::array<unsigned char, 16> b{};
  size_t got = 0;
  while (got < b.size()) {
    const ssize_t n = ::getrandom(b.data() + got, b.size() - got, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw std::runtime_error(fmt::format("getrandom: {}", std::strerror(errno)));
    got += static_cast<size_t>(n);
  }
  const auto ms = static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                            std::chrono::system_clock::now().time_since_epoch())
                                            .count());
  for (int i = 0; i < 6; ++i) b[i] = static_cast<unsigned char>(ms >> (40 - 8 * i));
  b[6] = static_cast<unsigned char>(0x70 | (b[6] & 0x0f));  // version 7
  b[8] = static_cast<unsigned char>(0x80 | (b[8] & 0x3f));  // variant 10
  std::string out;
  for (size_t i = 0; i < b.size(); ++i) {
    if (i == 4 || i == 6 || i == 8 || i == 10) out += '-';
    out += fmt::format("{:02x}", b[i]);
  }
  return out;
}

void mark_catalogue_pending(const std::filesystem::path& run_dir, const std::string& catalogue,
                            const std::string& what, const std::string& error) {
  write_json_atomic(run_dir / kCataloguePending,
                    {{"catalogue", catalogue}, {"what", what}, {"error", error}, {"marked_utc", utc_now_iso()}});
}

}  // namespace fpss
