// libFuzzer harness for the FPSS frame parser; the regression test replays the seed corpus through it.
// Checks, for any input: chunked feeding == whole feeding, byte accounting, re-encoding round trip.
#include <cstdio>
#include <cstdlib>

#include "drivers/fpss_frame.h"
#include "tests/support/fuzz_check.h"

namespace {
void check(bool ok, const char* what) { fpss::test::fuzz_check(ok, "frame parser", what); }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  using namespace fpss::frame;
  Parser whole;
  std::vector<Frame> a;
  whole.feed(data, size, a);

  // The same bytes in chunks whose sizes the input itself chooses: splits anywhere.
  Parser chunked;
  std::vector<Frame> b;
  for (std::size_t i = 0, k = 0; i < size; ++k) {
    std::size_t n = 1 + data[k % size] % 37;
    if (n > size - i) n = size - i;
    chunked.feed(data + i, n, b);
    i += n;
  }
  check(a == b, "chunked feeding gave other frames than whole feeding");
  const ParserStats &sw = whole.stats(), &sc = chunked.stats();
  check(sw.samples == sc.samples && sw.replies == sc.replies && sw.crc_errors == sc.crc_errors &&
            sw.garbage_bytes == sc.garbage_bytes && whole.pending() == chunked.pending(),
        "chunked feeding changed the statistics");
  check(sw.bytes_fed == size, "bytes_fed");

  std::size_t frame_bytes = 0;
  StreamTracker tracker;
  for (const Frame& f : a) {
    std::vector<uint8_t> e = encode(f);
    frame_bytes += e.size();
    Parser p;
    std::vector<Frame> back;
    p.feed(e.data(), e.size(), back);
    check(back.size() == 1 && back[0] == f, "re-encoded frame does not parse back to itself");
    if (const auto* s = std::get_if<SampleFrame>(&f)) {
      auto st = tracker.observe(s->seq, s->sensor_time_us);
      check(st.sensor_time_s >= 0, "negative sensor time");
    }
  }
  check(frame_bytes + sw.garbage_bytes + whole.pending() == size, "byte accounting");
  check(whole.pending() < kReplyOverhead + kMaxReplyText, "parser holds more than one frame's worth");
  check(sw.samples + sw.replies == a.size(), "frame counters");

  whole.reset();
  check(whole.pending() == 0 && whole.stats().garbage_bytes + frame_bytes == size, "reset accounting");
  return 0;
}
