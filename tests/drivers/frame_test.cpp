// Frame codec and parser: CRC check value, layout, split/merged/corrupted frames, garbage, seq gaps and wraps.
#include "drivers/fpss_frame.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/support/crc_reference.h"

using namespace fpss::frame;

namespace {

// Independent bitwise CRC-16/CCITT-FALSE, straight from the definition, over d[from, to).
uint16_t crc_bitwise(const std::vector<uint8_t>& d, std::size_t from, std::size_t to) {
  return fpss::test::crc_ccitt_false(d.data() + from, to - from);
}

std::vector<Frame> parse_all(const std::vector<uint8_t>& bytes, Parser& p, std::size_t chunk = 0) {
  std::vector<Frame> out;
  if (chunk == 0) chunk = bytes.size();
  for (std::size_t i = 0; i < bytes.size(); i += chunk)
    p.feed(bytes.data() + i, std::min(chunk, bytes.size() - i), out);
  return out;
}

SampleFrame sample(uint16_t seq, uint32_t t = 0) {
  SampleFrame s;
  s.seq = seq;
  s.sensor_time_us = t;
  s.counts_alpha = static_cast<int16_t>(seq * 7 - 1000);
  s.counts_beta = static_cast<int16_t>(-seq * 3);
  s.status = 0x07;
  return s;
}

// A mixed stream: samples with a reply every few frames.
std::vector<Frame> some_frames(int n) {
  std::vector<Frame> f;
  for (int i = 0; i < n; ++i) {
    f.push_back(sample(static_cast<uint16_t>(i), static_cast<uint32_t>(i) * 5000u));
    if (i % 4 == 2) f.push_back(Reply{"TEMP 21." + std::to_string(i)});
  }
  return f;
}

std::vector<uint8_t> encode_all(const std::vector<Frame>& frames) {
  std::vector<uint8_t> b;
  for (const auto& f : frames) {
    auto e = encode(f);
    b.insert(b.end(), e.begin(), e.end());
  }
  return b;
}

}  // namespace

TEST(Crc16, CheckValueOfTheStandard) {
  const char* s = "123456789";
  EXPECT_EQ(crc16_ccitt_false(reinterpret_cast<const uint8_t*>(s), 9), 0x29B1);
  EXPECT_EQ(crc16_ccitt_false(nullptr, 0), 0xFFFF);
}

TEST(Crc16, TableMatchesBitwiseDefinitionOnRandomData) {
  std::mt19937 rng(7);
  for (int n = 0; n < 300; ++n) {
    std::vector<uint8_t> d(static_cast<std::size_t>(n));
    for (auto& b : d) b = static_cast<uint8_t>(rng());
    EXPECT_EQ(crc16_ccitt_false(d.data(), d.size()), crc_bitwise(d, 0, d.size())) << "length " << n;
  }
}

TEST(Encode, SampleLayoutIsLittleEndianAsTheIcd) {
  SampleFrame s{0x0102, 0x03040506, -2, 0x1234, 0x0F};
  auto b = encode(s);
  ASSERT_EQ(b.size(), kSampleSize);
  std::vector<uint8_t> head{0xA5, 0x5A, 0x01, 0x02, 0x01, 0x06, 0x05, 0x04, 0x03, 0xFE, 0xFF, 0x34, 0x12, 0x0F};
  EXPECT_EQ(std::vector<uint8_t>(b.begin(), b.begin() + 14), head);
  uint16_t crc = crc_bitwise(b, 2, 14);
  EXPECT_EQ(b[14], crc & 0xFF);
  EXPECT_EQ(b[15], crc >> 8);
}

TEST(Encode, ReplyLayoutAndLengthLimit) {
  auto b = encode(Reply{"OK"});
  ASSERT_EQ(b.size(), 8u);
  EXPECT_EQ(b[2], 0x02);
  EXPECT_EQ(b[3], 2);
  EXPECT_EQ(b[4], 'O');
  EXPECT_EQ(b[5], 'K');
  uint16_t crc = crc_bitwise(b, 2, 6);
  EXPECT_EQ(b[6] | (b[7] << 8), crc);
  EXPECT_NO_THROW(encode(Reply{std::string(255, 'x')}));
  EXPECT_THROW(encode(Reply{std::string(256, 'x')}), std::length_error);
}

TEST(Parser, RoundTripsSamplesAndRepliesIncludingEdgeLengths) {
  std::vector<Frame> frames{SampleFrame{65535, 0xFFFFFFFF, -32768, 32767, 0xFF}, Reply{""}, Reply{std::string(255, 'Z')},
                            SampleFrame{0, 0, 0, 0, 0}};
  Parser p;
  EXPECT_EQ(parse_all(encode_all(frames), p), frames);
  EXPECT_EQ(p.stats().samples, 2u);
  EXPECT_EQ(p.stats().replies, 2u);
  EXPECT_EQ(p.stats().garbage_bytes, 0u);
  EXPECT_EQ(p.pending(), 0u);
}

TEST(Parser, MergedFramesInOneChunk) {
  auto frames = some_frames(200);
  Parser p;
  EXPECT_EQ(parse_all(encode_all(frames), p), frames);
}

TEST(Parser, ByteByByteFeeding) {
  auto frames = some_frames(40);
  Parser p;
  EXPECT_EQ(parse_all(encode_all(frames), p, 1), frames);
  EXPECT_EQ(p.stats().garbage_bytes, 0u);
}

TEST(Parser, EverySplitPointOfThreeFrames) {
  std::vector<Frame> frames{sample(1), Reply{"FPSS,SN=42,FW=1.0"}, sample(2)};
  auto bytes = encode_all(frames);
  for (std::size_t cut = 0; cut <= bytes.size(); ++cut) {
    Parser p;
    std::vector<Frame> out;
    p.feed(bytes.data(), cut, out);
    p.feed(bytes.data() + cut, bytes.size() - cut, out);
    EXPECT_EQ(out, frames) << "split at " << cut;
  }
}

TEST(Parser, RandomChunkSizes) {
  auto frames = some_frames(500);
  auto bytes = encode_all(frames);
  std::mt19937 rng(11);
  Parser p;
  std::vector<Frame> out;
  for (std::size_t i = 0; i < bytes.size();) {
    std::size_t n = std::min<std::size_t>(rng() % 40, bytes.size() - i);
    p.feed(bytes.data() + i, n, out);
    i += n;
  }
  EXPECT_EQ(out, frames);
}

// `out` is exactly the sample frames sample(seq) for these sequence numbers, in order.
void expect_samples(const std::vector<Frame>& out, std::initializer_list<uint16_t> seqs) {
  ASSERT_EQ(out.size(), seqs.size());
  std::size_t i = 0;
  for (uint16_t seq : seqs) EXPECT_EQ(std::get<SampleFrame>(out[i++]), sample(seq));
}

TEST(Parser, GarbageBeforeAndBetweenFramesIsCountedAndSkipped) {
  std::vector<uint8_t> b{0x00, 0x11, 0x5A, 0x01};  // 4 bytes of noise, no sync
  auto f1 = encode(sample(1));
  b.insert(b.end(), f1.begin(), f1.end());
  b.insert(b.end(), {0xA5, 0xA5, 0x13});  // a lone sync byte twice, then noise: 3 bytes
  auto f2 = encode(sample(2));
  b.insert(b.end(), f2.begin(), f2.end());
  Parser p;
  auto out = parse_all(b, p);
  expect_samples(out, {1, 2});
  EXPECT_EQ(p.stats().garbage_bytes, 7u);
  EXPECT_EQ(p.stats().crc_errors, 0u);
}

TEST(Parser, UnknownTypeAfterSyncIsGarbage) {
  std::vector<uint8_t> b{0xA5, 0x5A, 0x07};
  auto f = encode(sample(9));
  b.insert(b.end(), f.begin(), f.end());
  Parser p;
  auto out = parse_all(b, p);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(p.stats().garbage_bytes, 3u);
}

TEST(Parser, BadCrcDropsOnlyThatFrameAndCountsIt) {
  auto frames = some_frames(10);
  std::vector<uint8_t> b;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    auto e = encode(frames[i]);
    if (i == 4) e[7] ^= 0x40;  // a bit flip inside the body
    b.insert(b.end(), e.begin(), e.end());
  }
  Parser p;
  auto out = parse_all(b, p);
  auto expected = frames;
  expected.erase(expected.begin() + 4);
  EXPECT_EQ(out, expected);
  EXPECT_EQ(p.stats().crc_errors, 1u);
  EXPECT_EQ(p.stats().garbage_bytes, encode(frames[4]).size());
}

TEST(Parser, CorruptedCrcBytesAndTruncatedFrameAreDropped) {
  auto a = encode(sample(1)), c = encode(sample(3));
  auto bad = encode(sample(2));
  bad[15] ^= 0xFF;
  auto truncated = encode(sample(99));
  truncated.resize(9);  // the sensor was reset mid-frame
  std::vector<uint8_t> b = a;
  b.insert(b.end(), bad.begin(), bad.end());
  b.insert(b.end(), truncated.begin(), truncated.end());
  b.insert(b.end(), c.begin(), c.end());
  Parser p;
  auto out = parse_all(b, p);
  // The truncated frame's sync makes the parser read 16 bytes that include the start of frame 3:
  // that CRC fails, the parser resyncs from the next byte and still finds frame 3.
  expect_samples(out, {1, 3});
  EXPECT_EQ(p.stats().crc_errors, 2u);
  EXPECT_EQ(p.stats().garbage_bytes, 16u + 9u);
}

TEST(Parser, FalseSyncWithLongLengthDoesNotSwallowRealFrames) {
  // Noise that looks like the start of a 255-byte reply: the parser must wait for it, fail its CRC,
  // and find the real frames hidden inside.
  std::vector<uint8_t> b{0xA5, 0x5A, 0x02, 0xFF};
  auto frames = some_frames(30);
  auto real = encode_all(frames);
  b.insert(b.end(), real.begin(), real.end());
  Parser p;
  auto out = parse_all(b, p, 5);
  EXPECT_EQ(out, frames);
  EXPECT_EQ(p.stats().crc_errors, 1u);
  EXPECT_EQ(p.stats().garbage_bytes, 4u);
}

TEST(Parser, RandomNoiseBetweenFramesKeepsByteAccounting) {
  std::mt19937 rng(1234);
  std::vector<uint8_t> b;
  std::vector<Frame> frames;
  std::size_t frame_bytes = 0;
  for (int i = 0; i < 2000; ++i) {
    int noise = static_cast<int>(rng() % 6);
    for (int k = 0; k < noise; ++k) b.push_back(rng() % 3 == 0 ? 0xA5 : static_cast<uint8_t>(rng()));
    Frame f = (i % 7 == 3) ? Frame(Reply{"OK"}) : Frame(sample(static_cast<uint16_t>(i)));
    auto e = encode(f);
    frame_bytes += e.size();
    b.insert(b.end(), e.begin(), e.end());
    frames.push_back(f);
  }
  Parser p;
  auto out = parse_all(b, p, 61);
  EXPECT_EQ(out, frames);  // with this seed no noise happens to form a valid frame
  const auto& s = p.stats();
  EXPECT_EQ(s.bytes_fed, b.size());
  EXPECT_EQ(frame_bytes + s.garbage_bytes + p.pending(), b.size());
  EXPECT_GT(s.garbage_bytes, 3000u);
}

TEST(Parser, ResetCountsThePartialFrameAsGarbage) {
  auto f = encode(sample(5));
  Parser p;
  std::vector<Frame> out;
  p.feed(f.data(), 10, out);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(p.pending(), 10u);
  p.reset();
  EXPECT_EQ(p.pending(), 0u);
  EXPECT_EQ(p.stats().garbage_bytes, 10u);
  p.feed(f.data(), f.size(), out);
  EXPECT_EQ(out.size(), 1u);
}

TEST(StreamTracker, ConsecutiveSequenceHasNoGap) {
  StreamTracker t;
  for (uint16_t s = 100; s < 200; ++s) EXPECT_FALSE(t.observe(s, s * 5000u).gap);
  EXPECT_EQ(t.seq_gaps(), 0u);
  EXPECT_EQ(t.frames_lost(), 0u);
}

TEST(StreamTracker, GapCountsLostFrames) {
  StreamTracker t;
  t.observe(0, 0);
  t.observe(1, 5000);
  auto st = t.observe(4, 20000);
  EXPECT_TRUE(st.gap);
  EXPECT_EQ(st.lost, 2u);
  t.observe(5, 25000);
  EXPECT_EQ(t.seq_gaps(), 1u);
  EXPECT_EQ(t.frames_lost(), 2u);
}

TEST(StreamTracker, SequenceWrapIsNotAGapButAGapAcrossTheWrapIs) {
  StreamTracker t;
  t.observe(65534, 0);
  EXPECT_FALSE(t.observe(65535, 1).gap);
  EXPECT_FALSE(t.observe(0, 2).gap);
  EXPECT_FALSE(t.observe(1, 3).gap);
  auto st = t.observe(65533, 4);  // backwards: a restart, not 65531 lost frames
  EXPECT_TRUE(st.gap);
  EXPECT_EQ(st.lost, 0u);
  st = t.observe(2, 5);  // 65534, 65535, 0, 1 missing across the wrap
  EXPECT_TRUE(st.gap);
  EXPECT_EQ(st.lost, 4u);
  EXPECT_EQ(t.seq_gaps(), 2u);
  EXPECT_EQ(t.frames_lost(), 4u);
}

TEST(StreamTracker, SensorClockIsUnwrappedAcrossTheU32Wrap) {
  StreamTracker t;
  EXPECT_DOUBLE_EQ(t.observe(0, 0xFFFFFF00u).sensor_time_s, 0xFFFFFF00u * 1e-6);
  auto st = t.observe(1, 0x00000100u);  // 512 us later, after the wrap
  EXPECT_DOUBLE_EQ(st.sensor_time_s, (0x100000000ull + 0x100u) * 1e-6);
  // Many wraps: 4096 s steps keep accumulating.
  StreamTracker u;
  uint32_t raw = 0;
  uint64_t truth = 0;
  u.observe(0, 0);
  for (uint16_t s = 1; s <= 10; ++s) {
    raw += 4'096'000'000u;
    truth += 4'096'000'000ull;
    EXPECT_DOUBLE_EQ(u.observe(s, raw).sensor_time_s, static_cast<double>(truth) * 1e-6);
  }
}
