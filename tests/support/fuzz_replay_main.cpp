// Replays a libFuzzer corpus through LLVMFuzzerTestOneInput with the normal compiler (no clang
// needed): every file, plus every single-bit flip of the files up to 2 KiB. A harness signals a
// broken invariant by aborting, so the test fails on any crash, abort or uncaught exception.
#include <cstdio>
#include <filesystem>

#include "tests/support/fuzz_replay.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR...\n", argv[0]);
    return 2;
  }
  constexpr std::size_t kFlipUpTo = 2048;
  int files = 0;
  long inputs = 0;
  for (int a = 1; a < argc; ++a) {
    for (const auto& entry : std::filesystem::directory_iterator(argv[a])) {
      if (!entry.is_regular_file()) continue;
      auto data = fpss::test::read_corpus_file(entry.path());
      ++files;
      inputs += fpss::test::replay_with_bit_flips(data, kFlipUpTo);
    }
  }
  std::printf("replayed %d corpus files (%ld inputs with bit flips)\n", files, inputs);
  return files > 0 ? 0 : 1;
}
