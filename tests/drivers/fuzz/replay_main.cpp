// Replays the fuzz seed corpus through LLVMFuzzerTestOneInput with the normal compiler, plus every
// single-bit flip of each seed; checks the frame counts make_corpus.py expects for each seed.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "drivers/fpss_frame.h"
#include "tests/support/fuzz_replay.h"

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR EXPECTED_FILE\n", argv[0]);
    return 2;
  }
  std::map<std::string, std::tuple<uint64_t, uint64_t, uint64_t>> expected;
  std::ifstream ex(argv[2]);
  for (std::string line; std::getline(ex, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream is(line);
    std::string name;
    uint64_t s, r, c;
    if (is >> name >> s >> r >> c) expected[name] = {s, r, c};
  }
  int files = 0, failures = 0;
  long inputs = 0;
  for (const auto& entry : std::filesystem::directory_iterator(argv[1])) {
    if (!entry.is_regular_file()) continue;
    auto data = fpss::test::read_corpus_file(entry.path());
    ++files;
    inputs += fpss::test::replay_with_bit_flips(data, std::numeric_limits<std::size_t>::max());
    auto it = expected.find(entry.path().filename().string());
    if (it != expected.end()) {
      fpss::frame::Parser p;
      std::vector<fpss::frame::Frame> frames;
      p.feed(data.data(), data.size(), frames);
      auto [s, r, c] = it->second;
      const auto& st = p.stats();
      if (st.samples != s || st.replies != r || st.crc_errors != c) {
        std::fprintf(stderr, "%s: parsed %llu samples, %llu replies, %llu CRC errors; expected %llu, %llu, %llu\n",
                     it->first.c_str(), (unsigned long long)st.samples, (unsigned long long)st.replies,
                     (unsigned long long)st.crc_errors, (unsigned long long)s, (unsigned long long)r,
                     (unsigned long long)c);
        ++failures;
      }
      expected.erase(it);
    }
  }
  for (const auto& [name, v] : expected) {
    std::fprintf(stderr, "%s: expected in the corpus, missing\n", name.c_str());
    ++failures;
  }
  std::printf("replayed %d seeds (%ld inputs with bit flips), %d failures\n", files, inputs, failures);
  return files > 0 && failures == 0 ? 0 : 1;
}
