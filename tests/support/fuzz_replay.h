// Replays one input through a libFuzzer harness with the normal compiler: the input as it is, then
// every single-bit flip of it. A harness signals a broken invariant by aborting.
#pragma once
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size);

namespace fpss::test {

inline std::vector<uint8_t> read_corpus_file(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Runs `data` and, when it is at most `flip_up_to` bytes, each single-bit flip of it; returns
// how many inputs ran. `data` is unchanged on return.
inline long replay_with_bit_flips(std::vector<uint8_t>& data, std::size_t flip_up_to) {
  LLVMFuzzerTestOneInput(data.data(), data.size());
  long inputs = 1;
  if (data.size() > flip_up_to) return inputs;
  for (std::size_t bit = 0; bit < data.size() * 8; ++bit) {
    data[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
    LLVMFuzzerTestOneInput(data.data(), data.size());
    data[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
    ++inputs;
  }
  return inputs;
}

}  // namespace fpss::test
