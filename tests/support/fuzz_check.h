// What every libFuzzer harness does when an invariant breaks: say which, then abort (a crash the fuzzer keeps).
#pragma once
#include <cstdio>
#include <cstdlib>

namespace fpss::test {

// `subject` names what is fuzzed ("stand reader"), `what` the broken invariant.
inline void fuzz_check(bool ok, const char* subject, const char* what) {
  if (ok) return;
  std::fprintf(stderr, "%s invariant violated: %s\n", subject, what);
  std::abort();
}

}  // namespace fpss::test
