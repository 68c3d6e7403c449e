#include "stand/cli/file_hints.h"

#include <fcntl.h>
#include <unistd.h>

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <set>
#include <vector>

#include "base/unique_fd.h"

namespace fpss::cli {

namespace fs = std::filesystem;

namespace {

struct Expected {
  CLI::App* sub;
  CLI::Option* opt;
  const std::string* path;
  FileKind kind;
};

std::vector<Expected>& registry() {
  static std::vector<Expected> r;
  return r;
}

const char* kind_name(FileKind k) {
  switch (k) {
    case FileKind::samples: return "a samples CSV";
    case FileKind::coefficients: return "a coefficient file";
    case FileKind::procedure: return "a procedure file";
    case FileKind::stand: return "a stand file";
    case FileKind::bench: return "an emulator bench file";
    case FileKind::limits: return "an acceptance limits file";
    case FileKind::run_folder: return "a run folder";
    case FileKind::unknown: break;
  }
  return "";
}

// Where a file of this kind goes when the command in hand takes none.
const char* elsewhere(FileKind k) {
  switch (k) {
    case FileKind::samples: return "calibrate and diagnose take it with --data";
    case FileKind::coefficients: return "angles and diagnose take it with --model, calibrate with --init or --truth";
    case FileKind::procedure: return "run takes it first: fpss-stand run PROCEDURE.yaml --emulate";
    case FileKind::stand: return "run, accept, design and serve take it with --stand";
    case FileKind::bench: return "emulate takes it with --bench (run, accept and design with --emulate --bench)";
    case FileKind::limits: return "accept takes it with --limits";
    case FileKind::run_folder: return "show and report take it, and run --resume";
    case FileKind::unknown: break;
  }
  return "";
}

std::string shown(const CLI::Option* opt) {
  return opt->get_lnames().empty() ? opt->get_name() : "--" + opt->get_lnames().front();
}

// The top-level keys of a YAML text: names at column 0 followed by ':'.
std::set<std::string> yaml_keys(const std::string& head) {
  std::set<std::string> keys;
  size_t at = 0;
  while (at < head.size()) {
    size_t end = head.find('\n', at);
    if (end == std::string::npos) end = head.size();
    const std::string line = head.substr(at, end - at);
    size_t n = 0;
    while (n < line.size() && (std::isalnum(static_cast<unsigned char>(line[n])) || line[n] == '_')) ++n;
    if (n > 0 && n < line.size() && line[n] == ':') keys.insert(line.substr(0, n));
    at = end + 1;
  }
  return keys;
}

FileKind kind_of_text(const std::string& head) {
  const size_t first = head.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return FileKind::unknown;
  const std::string first_line = head.substr(first, head.find('\n', first) - first);
  if (head[first] == '{') {
    // A coefficient file: "alpha": [ the eight numbers.
    const size_t a = head.find("\"alpha\"");
    if (a != std::string::npos && head.find_first_not_of(" \t\r\n:", a + 7) != std::string::npos &&
        head[head.find_first_not_of(" \t\r\n:", a + 7)] == '[') {
      return FileKind::coefficients;
    }
    return FileKind::unknown;
  }
  if (first_line.find(',') != std::string::npos &&
      (first_line.find("counts_alpha") != std::string::npos || first_line.find("ref_pitch_arcsec") != std::string::npos)) {
    return FileKind::samples;
  }
  const auto keys = yaml_keys(head);
  if (keys.count("steps")) return FileKind::procedure;
  if (keys.count("limits")) return FileKind::limits;
  if (keys.count("gimbal") || keys.count("sensor")) return FileKind::stand;
  for (const char* k : {"mount", "truth", "count_noise", "encoder_noise_arcsec", "max_rate_arcsec_s", "sample_rate_hz",
                        "temperature", "timed_moves", "effects"}) {
    if (keys.count(k)) return FileKind::bench;
  }
  return FileKind::unknown;
}

}  // namespace

FileKind sniff_file_kind(const fs::path& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec) return FileKind::unknown;
  if (fs::is_directory(st)) return fs::is_regular_file(path / "run.json", ec) ? FileKind::run_folder : FileKind::unknown;
  if (!fs::is_regular_file(st)) return FileKind::unknown;
  UniqueFd fd(::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC));
  if (!fd) return FileKind::unknown;
  std::string head(16384, '\0');
  const ssize_t n = ::read(fd.get(), head.data(), head.size());
  if (n <= 0) return FileKind::unknown;
  head.resize(static_cast<size_t>(n));
  return kind_of_text(head);
}

void expect_file(CLI::App* sub, CLI::Option* opt, const std::string& path, FileKind kind) {
  registry().push_back({sub, opt, &path, kind});
}

std::string file_hint(const std::string& message) {
  for (const Expected& e : registry()) {
    if (e.opt->count() == 0 || e.path->empty() || message.find(*e.path) == std::string::npos) continue;
    const FileKind got = sniff_file_kind(*e.path);
    if (got == FileKind::unknown || got == e.kind) continue;
    const std::string what = fmt::format("hint: {} is {}", *e.path, kind_name(got));
    // A run folder where one of its files is wanted: name that file.
    const fs::path dir = *e.path;
    if (got == FileKind::run_folder && e.kind == FileKind::samples && fs::exists(dir / "samples.csv")) {
      return fmt::format("{}; its recording is {}", what, (dir / "samples.csv").string());
    }
    if (got == FileKind::run_folder && e.kind == FileKind::coefficients && fs::exists(dir / "calibration.json")) {
      return fmt::format("{}; its calibration is {}", what, (dir / "calibration.json").string());
    }
    std::vector<std::string> takers;
    for (const Expected& o : registry()) {
      if (o.sub == e.sub && o.kind == got) takers.push_back(shown(o.opt));
    }
    if (takers.empty()) return fmt::format("{}; {}", what, elsewhere(got));
    std::string list = takers.front();
    for (size_t k = 1; k < takers.size(); ++k) list += (k + 1 == takers.size() ? " or " : ", ") + takers[k];
    if (takers.front().rfind("--", 0) != 0) {  // a positional: its name as the usage line spells it
      std::transform(list.begin(), list.end(), list.begin(), [](unsigned char c) { return std::toupper(c); });
      return fmt::format("{}; {} takes it as {}", what, e.sub->get_name(), list);
    }
    return fmt::format("{}; {} takes it with {}", what, e.sub->get_name(), list);
  }
  return {};
}

}  // namespace fpss::cli
