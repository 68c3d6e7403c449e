// CRC-16/CCITT-FALSE written bit by bit from its definition, for checking both frame codecs (drivers and fixtures) against.
#pragma once
#include <cstddef>
#include <cstdint>

namespace fpss::test {

inline uint16_t crc_ccitt_false(const uint8_t* d, std::size_t n) {
  uint16_t crc = 0xFFFF;
  for (std::size_t i = 0; i < n; ++i) {
    crc ^= static_cast<uint16_t>(d[i] << 8);
    for (int b = 0; b < 8; ++b) crc = (crc & 0x8000) ? static_cast<uint16_t>((crc << 1) ^ 0x1021) : static_cast<uint16_t>(crc << 1);
  }
  return crc;
}

}  // namespace fpss::test
