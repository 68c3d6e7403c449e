#include "stand/cli/file_options.h"

#include <fmt/format.h>

#include <filesystem>
#include <utility>

#include "base/errors.h"
#include "base/text_file.h"

namespace fpss::cli {

namespace fs = std::filesystem;

namespace {

// The option's name as a user types it: "--out" of "--out,-o", "COEFFS" of a positional.
std::string shown_name(const CLI::Option* opt) {
  return opt->get_lnames().empty() ? opt->get_name() : "--" + opt->get_lnames().front();
}

// Two files that exist are the same by device and inode; one not written yet by its spelling with
// links and ../ resolved.
bool same_file(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec);
  const auto spelt = [](const fs::path& p) {
    std::error_code e;
    const fs::path c = fs::weakly_canonical(p, e);
    return e ? fs::absolute(p).lexically_normal() : c;
  };
  return spelt(a) == spelt(b);
}

}  // namespace

CLI::Option* FileOptions::input(CLI::App* sub, const std::string& name, std::string& path, const std::string& help) {
  CLI::Option* opt = sub->add_option(name, path, help);
  inputs_.push_back({shown_name(opt), &path, {}});
  return opt;
}

void FileOptions::inputs(const std::string& option, std::vector<std::string>& paths) {
  (void)option;
  input_lists_.push_back(&paths);
}

CLI::Option* FileOptions::output(CLI::App* sub, const std::string& name, std::string& path, const std::string& help,
                                 Beside beside) {
  CLI::Option* opt = sub->add_option(name, path, help);
  outputs_.push_back({shown_name(opt), &path, std::move(beside)});
  return opt;
}

void FileOptions::check() const {
  std::vector<fs::path> read;
  for (const auto& f : inputs_) read.emplace_back(*f.path);
  for (const auto* list : input_lists_) read.insert(read.end(), list->begin(), list->end());
  // Every file the given outputs write, with the option that names it.
  std::vector<std::pair<std::string, fs::path>> written;
  for (const auto& f : outputs_) {
    if (f.path->empty()) continue;
    written.emplace_back(f.option, *f.path);
    if (f.beside) written.emplace_back(f.option, f.beside(*f.path));
  }
  for (size_t i = 0; i < written.size(); ++i) {
    const auto& [option, path] = written[i];
    check_output_path(path, read, option);
    for (size_t k = 0; k < i; ++k) {
      if (same_file(path, written[k].second)) {
        throw InputError(fmt::format("{} {}: the same file as {}", option, path.string(), written[k].first));
      }
    }
  }
}

}  // namespace fpss::cli
