// The files a sub-command reads and writes, declared with its options and checked together before it starts.
#pragma once
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace fpss::cli {

// Each output is checked as base/text_file.h's check_output_path checks one (its folder exists and
// is writable; it is no input, however spelt), and no two outputs are the same file: a command that
// names its files here cannot forget one of them in its checks.
class FileOptions {
 public:
  // `path` is where the option's value goes; it must outlive check() (a field of the same options).
  CLI::Option* input(CLI::App* sub, const std::string& name, std::string& path, const std::string& help);
  // Files an option names inside its values (diagnose --model SERIAL=FILE): `paths` is filled from
  // the values before check(), which then reads them as inputs of `option`.
  void inputs(const std::string& option, std::vector<std::string>& paths);
  // `beside`, when the output may bring a second file named after it (diagnose --emit-bench's
  // refitted transfer function): that file is checked as an output of the same option.
  using Beside = std::function<std::filesystem::path(const std::string& path)>;
  CLI::Option* output(CLI::App* sub, const std::string& name, std::string& path, const std::string& help,
                      Beside beside = {});

  // InputError (exit 2) naming the option; outputs not given are skipped.
  void check() const;

 private:
  struct File {
    std::string option;
    const std::string* path;
    Beside beside{};
  };
  std::vector<File> inputs_, outputs_;
  std::vector<std::vector<std::string>*> input_lists_;
};

}  // namespace fpss::cli
