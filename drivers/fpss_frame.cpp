// FPSS serial frames: CRC, encoder, incremental parser and stream tracker. Standard library only
// (the fuzz harness compiles this file on its own with sanitizer flags).
#include "drivers/fpss_frame.h"

#include <array>
#include <cstring>
#include <stdexcept>

namespace fpss::frame {
namespace {

constexpr std::array<uint16_t, 256> make_crc_table() {
  std::array<uint16_t, 256> t{};
  for (int i = 0; i < 256; ++i) {
    uint16_t c = static_cast<uint16_t>(i << 8);
    for (int b = 0; b < 8; ++b) c = static_cast<uint16_t>((c & 0x8000) ? (c << 1) ^ 0x1021 : c << 1);
    t[i] = c;
  }
  return t;
}
constexpr std::array<uint16_t, 256> kCrcTable = make_crc_table();

inline uint16_t rd16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
inline uint32_t rd32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) | (static_cast<uint32_t>(p[2]) << 16) |
         (static_cast<uint32_t>(p[3]) << 24);
}
inline void wr16(std::vector<uint8_t>& o, uint16_t v) {
  o.push_back(static_cast<uint8_t>(v & 0xFF));
  o.push_back(static_cast<uint8_t>(v >> 8));
}

}  // namespace

uint16_t crc16_ccitt_false(const uint8_t* data, std::size_t n, uint16_t crc) {
  for (std::size_t i = 0; i < n; ++i) crc = static_cast<uint16_t>((crc << 8) ^ kCrcTable[((crc >> 8) ^ data[i]) & 0xFF]);
  return crc;
}

void append_sample(std::vector<uint8_t>& out, const SampleFrame& s) {
  std::size_t start = out.size();
  out.push_back(kSync0);
  out.push_back(kSync1);
  out.push_back(kTypeSample);
  wr16(out, s.seq);
  wr16(out, static_cast<uint16_t>(s.sensor_time_us & 0xFFFF));
  wr16(out, static_cast<uint16_t>(s.sensor_time_us >> 16));
  wr16(out, static_cast<uint16_t>(s.counts_alpha));
  wr16(out, static_cast<uint16_t>(s.counts_beta));
  out.push_back(s.status);
  wr16(out, crc16_ccitt_false(out.data() + start + 2, out.size() - start - 2));
}

void append_reply(std::vector<uint8_t>& out, std::string_view text) {
  if (text.size() > kMaxReplyText)
    throw std::length_error("FPSS reply text of " + std::to_string(text.size()) + " bytes exceeds 255");
  std::size_t start = out.size();
  out.push_back(kSync0);
  out.push_back(kSync1);
  out.push_back(kTypeReply);
  out.push_back(static_cast<uint8_t>(text.size()));
  out.insert(out.end(), text.begin(), text.end());
  wr16(out, crc16_ccitt_false(out.data() + start + 2, out.size() - start - 2));
}

std::vector<uint8_t> encode(const Frame& f) {
  std::vector<uint8_t> out;
  if (auto* s = std::get_if<SampleFrame>(&f))
    append_sample(out, *s);
  else
    append_reply(out, std::get<Reply>(f).text);
  return out;
}

bool Parser::next(Frame& out) {
  for (;;) {
    const uint8_t* b = buf_.data();
    const std::size_t end = buf_.size();
    // Hunt for the first sync byte; everything before it is noise.
    if (pos_ < end && b[pos_] != kSync0) {
      const void* hit = std::memchr(b + pos_, kSync0, end - pos_);
      std::size_t at = hit ? static_cast<std::size_t>(static_cast<const uint8_t*>(hit) - b) : end;
      stats_.garbage_bytes += at - pos_;
      pos_ = at;
    }
    if (end - pos_ < 3) return false;  // need sync + type
    if (b[pos_ + 1] != kSync1) {
      ++stats_.garbage_bytes;
      ++pos_;
      continue;
    }
    std::size_t size;
    const uint8_t type = b[pos_ + 2];
    if (type == kTypeSample) {
      size = kSampleSize;
    } else if (type == kTypeReply) {
      if (end - pos_ < 4) return false;
      size = kReplyOverhead + b[pos_ + 3];
    } else {
      ++stats_.garbage_bytes;  // not a frame start after all
      ++pos_;
      continue;
    }
    if (end - pos_ < size) return false;
    const uint8_t* f = b + pos_;
    if (crc16_ccitt_false(f + 2, size - 4) != rd16(f + size - 2)) {
      ++stats_.crc_errors;
      ++stats_.garbage_bytes;  // resync from the byte after this sync
      ++pos_;
      continue;
    }
    if (type == kTypeSample) {
      SampleFrame s;
      s.seq = rd16(f + 3);
      s.sensor_time_us = rd32(f + 5);
      s.counts_alpha = static_cast<int16_t>(rd16(f + 9));
      s.counts_beta = static_cast<int16_t>(rd16(f + 11));
      s.status = f[13];
      out = s;
      ++stats_.samples;
    } else {
      out = Reply{std::string(reinterpret_cast<const char*>(f + 4), f[3])};
      ++stats_.replies;
    }
    pos_ += size;
    return true;
  }
}

void Parser::compact() {
  if (pos_ == buf_.size()) {
    buf_.clear();
    pos_ = 0;
  } else if (pos_ > 4096) {
    buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(pos_));
    pos_ = 0;
  }
}

void Parser::reset() {
  stats_.garbage_bytes += buf_.size() - pos_;
  buf_.clear();
  pos_ = 0;
}

StreamTracker::Step StreamTracker::observe(uint16_t seq, uint32_t sensor_time_us) {
  Step st;
  if (!started_) {
    started_ = true;
    unwrapped_us_ = sensor_time_us;
  } else {
    uint16_t expected = static_cast<uint16_t>(last_seq_ + 1);
    if (seq != expected) {
      st.gap = true;
      ++gaps_;
      uint16_t ahead = static_cast<uint16_t>(seq - expected);
      // More than half the range ahead is a jump backwards (a restarted sensor), not 30000 lost frames.
      if (ahead < 0x8000) {
        st.lost = ahead;
        lost_ += ahead;
      }
    }
    // Modular difference: the u32 clock wraps every ~71.6 min; lost frames in between do not matter.
    unwrapped_us_ += static_cast<uint32_t>(sensor_time_us - last_time_us_);
  }
  last_seq_ = seq;
  last_time_us_ = sensor_time_us;
  st.sensor_time_s = static_cast<double>(unwrapped_us_) * 1e-6;
  return st;
}

}  // namespace fpss::frame
