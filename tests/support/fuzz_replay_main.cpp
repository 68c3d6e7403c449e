// Replays a libFuzzer corpus through LLVMFuzzerTestOneInput with the normal compiler (no clang
// needed): every file, plus every single-bit flip of the files up to 2 KiB. A harness signals a
// broken invariant by aborting, so the test fails on any crash, abort or uncaught exception.
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size);

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
      std::ifstream in(entry.path(), std::ios::binary);
      std::vector<uint8_t> data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      ++files;
      LLVMFuzzerTestOneInput(data.data(), data.size());
      ++inputs;
      if (data.size() > kFlipUpTo) continue;
      for (std::size_t bit = 0; bit < data.size() * 8; ++bit) {
        data[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
        LLVMFuzzerTestOneInput(data.data(), data.size());
        data[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
        ++inputs;
      }
    }
  }
  std::printf("replayed %d corpus files (%ld inputs with bit flips)\n", files, inputs);
  return files > 0 ? 0 : 1;
}
