// What the harnesses of the YAML readers (procedure files, stand files) share: the input read as the
// file fuzz.yaml, only InputError let through, and every diagnostic placed in that file.
#pragma once
#include <cstdint>

#include "base/errors.h"
#include "procedures/yaml_diag.h"
#include "tests/support/fuzz_check.h"

namespace fpss::test {

inline constexpr const char* kFuzzFile = "fuzz.yaml";

// Reads the input with `read(text, file, diagnostics)`; what a text without diagnostics gives goes
// to `check_clean`, which judges it with `check`. Either may throw InputError.
template <typename Read, typename CheckClean>
void fuzz_yaml_reader(const uint8_t* data, std::size_t size, const Invariants& check, Read read,
                      CheckClean check_clean) {
  Diagnostics d(kFuzzFile);
  try {
    const auto result = read(fuzz_text(data, size), kFuzzFile, d);
    if (d.empty()) check_clean(result);
  } catch (const InputError&) {
  }
  for (const auto& e : d.all()) check(e.file == kFuzzFile && !e.message.empty(), "a diagnostic without a place");
}

}  // namespace fpss::test
