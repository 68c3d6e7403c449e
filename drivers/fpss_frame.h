// FPSS serial frames (docs/icd.md): CRC-16/CCITT-FALSE, encoder, incremental parser, sequence/clock tracker.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace fpss::frame {

inline constexpr uint8_t kSync0 = 0xA5, kSync1 = 0x5A;
inline constexpr uint8_t kTypeSample = 0x01, kTypeReply = 0x02;
inline constexpr std::size_t kSampleSize = 16;       // sync 2, type 1, body 11, crc 2
inline constexpr std::size_t kReplyOverhead = 6;     // sync 2, type 1, len 1, crc 2
inline constexpr std::size_t kMaxReplyText = 255;

// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no xorout; "123456789" -> 0x29B1.
uint16_t crc16_ccitt_false(const uint8_t* data, std::size_t n, uint16_t crc = 0xFFFF);

struct SampleFrame {
  uint16_t seq = 0;
  uint32_t sensor_time_us = 0;
  int16_t counts_alpha = 0, counts_beta = 0;
  uint8_t status = 0;
  bool operator==(const SampleFrame&) const = default;
};

struct Reply {
  std::string text;
  bool operator==(const Reply&) const = default;
};

using Frame = std::variant<SampleFrame, Reply>;

void append_sample(std::vector<uint8_t>& out, const SampleFrame& s);
// Throws std::length_error for text longer than 255 bytes.
void append_reply(std::vector<uint8_t>& out, std::string_view text);
std::vector<uint8_t> encode(const Frame& f);

struct ParserStats {
  uint64_t samples = 0;        // good sample frames
  uint64_t replies = 0;        // good reply frames
  uint64_t crc_errors = 0;     // frames dropped for a bad CRC
  // Every byte fed that ended up in no good frame: noise before a sync, unknown frame types,
  // and the bytes of frames dropped for a bad CRC. Good frame bytes + garbage + pending == fed.
  uint64_t garbage_bytes = 0;
  uint64_t bytes_fed = 0;
};

// Incremental parser: feed byte chunks of any size, frames come out in order through a sink.
// After a bad CRC it resynchronises from the byte after that frame's sync, so a false sync in
// noise can never swallow a real frame.
class Parser {
 public:
  template <class Sink>  // void(const Frame&) or void(SampleFrame&&/Reply&&) via std::visit in the caller
  void feed(const uint8_t* data, std::size_t n, Sink&& sink) {
    buf_.insert(buf_.end(), data, data + n);
    stats_.bytes_fed += n;
    Frame f;
    while (next(f)) sink(f);
    compact();
  }
  void feed(const uint8_t* data, std::size_t n, std::vector<Frame>& out) {
    feed(data, n, [&out](const Frame& f) { out.push_back(f); });
  }
  // Drops a partial frame (counted as garbage), e.g. when the link was reopened.
  void reset();
  std::size_t pending() const { return buf_.size() - pos_; }
  const ParserStats& stats() const { return stats_; }

 private:
  bool next(Frame& out);  // one good frame from buf_[pos_..], or false when more bytes are needed
  void compact();
  std::vector<uint8_t> buf_;
  std::size_t pos_ = 0;
  ParserStats stats_;
};

// Follows one sample stream: sequence gaps (u16, wraps) and the unwrapped sensor clock (u32 us, wraps).
class StreamTracker {
 public:
  struct Step {
    bool gap = false;       // seq was not the previous seq + 1
    uint32_t lost = 0;      // frames missing by seq (0 for a backward jump, which is a restart)
    double sensor_time_s = 0;
  };
  Step observe(uint16_t seq, uint32_t sensor_time_us);
  void reset() { started_ = false; }
  uint64_t seq_gaps() const { return gaps_; }
  uint64_t frames_lost() const { return lost_; }

 private:
  bool started_ = false;
  uint16_t last_seq_ = 0;
  uint32_t last_time_us_ = 0;
  uint64_t unwrapped_us_ = 0;
  uint64_t gaps_ = 0, lost_ = 0;
};

}  // namespace fpss::frame
