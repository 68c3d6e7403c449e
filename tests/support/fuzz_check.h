// What every libFuzzer harness shares: its input as text, and what it does when an invariant breaks
// (say which, then abort: a crash the fuzzer keeps).
#pragma once
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

namespace fpss::test {

// `subject` names what is fuzzed ("stand reader"), `what` the broken invariant.
inline void fuzz_check(bool ok, const char* subject, const char* what) {
  if (ok) return;
  std::fprintf(stderr, "%s invariant violated: %s\n", subject, what);
  std::abort();
}

// The invariants of one subject: `check(ok, what)`.
struct Invariants {
  const char* subject;
  void operator()(bool ok, const char* what) const { fuzz_check(ok, subject, what); }
};

inline std::string_view fuzz_text(const uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

}  // namespace fpss::test
