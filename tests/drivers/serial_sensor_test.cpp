// SerialSensor over a real pty whose far end the test plays: commands, replies, samples, faults.
#include "drivers/serial_sensor.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>

#include "drivers/endpoints.h"
#include "test_util.h"

using testing::HasSubstr;
namespace fpss {
namespace {

using test::error_of;
using test::FakeElectronics;
using test::wait_until;

double steady_now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::optional<std::string> standard_answers(const std::string& line) {
  if (line == "ID?") return "FPSS,SN=0042,FW=1.3.0";
  if (line == "TEMP?") return "TEMP 23.75";
  if (line == "START" || line == "STOP") return "OK";
  if (line.rfind("RATE ", 0) == 0) return "OK";
  return "ERR unknown command";
}

SensorOptions options_for(const std::string& endpoint) {
  SensorOptions o;
  o.endpoint = endpoint;
  o.command_timeout_s = 5.0;  // generous: a loaded machine must not cause an unexpected retry
  o.command_retries = 1;
  o.reconnects = 1;
  o.reconnect_backoff_s = 0.02;
  return o;
}

frame::SampleFrame sample(uint16_t seq, uint32_t t_us, int16_t a = 100, int16_t b = -100) {
  return frame::SampleFrame{seq, t_us, a, b, 0x07};
}

struct SensorOnPty : testing::Test {
  test::PtyPair pty;
  FakeElectronics fake{pty.master(), standard_answers};
  std::unique_ptr<Sensor> sensor;
  void SetUp() override {
    sensor = make_sensor(options_for("pty:" + pty.slave_path()));
    sensor->connect();
  }
};

TEST_F(SensorOnPty, IdentifyTemperatureAndOkCommands) {
  EXPECT_TRUE(sensor->connected());
  EXPECT_EQ(sensor->identify(), "FPSS,SN=0042,FW=1.3.0");
  EXPECT_DOUBLE_EQ(sensor->temperature_c(), 23.75);
  sensor->set_rate(200);
  sensor->start();
  sensor->stop();
  EXPECT_EQ(fake.lines(), (std::vector<std::string>{"ID?", "TEMP?", "RATE 200", "START", "STOP"}));
  EXPECT_EQ(sensor->stats().replies, 5u);
}

TEST_F(SensorOnPty, ErrReplyIsADeviceErrorWithTheReasonAndNotRetried) {
  // (RATE is taken while streaming, docs/icd.md: this unit refuses it for a reason of its own.)
  fake.set_handler([](const std::string& l) -> std::optional<std::string> {
    if (l.rfind("RATE", 0) == 0) return "ERR rate not supported by this unit";
    return standard_answers(l);
  });
  std::string msg = error_of([&] { sensor->set_rate(50); });
  EXPECT_THAT(msg, HasSubstr("rate not supported by this unit"));
  EXPECT_THAT(msg, HasSubstr("'RATE 50' refused"));
  EXPECT_EQ(fake.lines().size(), 1u);
}

TEST_F(SensorOnPty, AnImplausibleTemperatureIsAnInvalidReadingNamingTheValueAndTheRange) {
  auto answer = [&](std::string reply) {
    fake.set_handler([reply](const std::string& l) -> std::optional<std::string> {
      return l == "TEMP?" ? std::optional<std::string>(reply) : standard_answers(l);
    });
  };
  auto temperature_with = [&](std::string reply) {
    answer(std::move(reply));
    return error_of([&] { sensor->temperature_c(); });
  };
  EXPECT_THAT(temperature_with("TEMP 2021.002"),
              HasSubstr("sensor temperature 2021.002 °C outside the plausible range -60..100 °C"));
  // The range's ends are plausible; just beyond them is not.
  answer("TEMP -60.00");
  EXPECT_DOUBLE_EQ(sensor->temperature_c(), -60.0);
  answer("TEMP 100");
  EXPECT_DOUBLE_EQ(sensor->temperature_c(), 100.0);
  EXPECT_THAT(temperature_with("TEMP -60.01"), HasSubstr("-60.01 °C outside"));
  // Only plain decimal notation is a temperature (docs/icd.md): no exponent, plus sign or words.
  for (const char* bad : {"TEMP 2.1e1", "TEMP +21.5", "TEMP 21.", "TEMP .5", "TEMP nan", "TEMP 21.5 C", "TEMP  21.5"}) {
    EXPECT_THAT(temperature_with(bad), HasSubstr("expected 'TEMP <celsius>'")) << bad;
  }
}

TEST(SensorOnPtyRange, TheStandsTemperatureRangeIsTheOneChecked) {
  test::PtyPair pty;
  FakeElectronics fake{pty.master(), [](const std::string& l) -> std::optional<std::string> {
                         return l == "TEMP?" ? std::optional<std::string>("TEMP 150.5") : standard_answers(l);
                       }};
  SensorOptions o = options_for("pty:" + pty.slave_path());
  o.temperature_min_c = -40;
  o.temperature_max_c = 200;
  const auto sensor = make_sensor(o);
  sensor->connect();
  EXPECT_DOUBLE_EQ(sensor->temperature_c(), 150.5);
}

TEST_F(SensorOnPty, RateIsValidatedBeforeSending) {
  EXPECT_THROW(sensor->set_rate(0), LimitError);
  EXPECT_THAT(error_of([&] { sensor->set_rate(201); }), HasSubstr("201 Hz outside 1..200"));
  sensor->set_rate(1);
  EXPECT_EQ(fake.lines(), std::vector<std::string>{"RATE 1"});
}

TEST_F(SensorOnPty, UnparseableTemperatureIsAClearError) {
  fake.set_handler([](const std::string&) -> std::optional<std::string> { return "TEMP warm"; });
  EXPECT_THAT(error_of([&] { sensor->temperature_c(); }), HasSubstr("'TEMP warm'"));
}

TEST(SerialSensor, LostReplyIsRetriedThenSucceeds) {
  test::PtyPair pty;
  std::atomic<int> starts{0};
  FakeElectronics fake(pty.master(), [&](const std::string& l) -> std::optional<std::string> {
    if (l == "START" && ++starts == 1) return std::nullopt;  // the first answer is lost
    return standard_answers(l);
  });
  SensorOptions o = options_for("pty:" + pty.slave_path());
  o.command_timeout_s = 1.0;
  o.command_retries = 3;
  SerialSensor sensor(o);
  sensor.connect();
  sensor.start();
  auto lines = fake.lines();
  ASSERT_GE(lines.size(), 2u);  // a loaded machine may need one more; every one is START
  EXPECT_EQ(lines, std::vector<std::string>(lines.size(), "START"));
}

TEST(SerialSensor, SilentSensorEndsInAClearErrorAfterRetries) {
  test::PtyPair pty;
  FakeElectronics fake(pty.master());  // hears everything, answers nothing
  SensorOptions o = options_for("pty:" + pty.slave_path());
  o.command_timeout_s = 0.3;
  SerialSensor sensor(o);
  sensor.connect();
  std::string msg = error_of([&] { sensor.identify(); });
  EXPECT_THAT(msg, HasSubstr("no reply to 'ID?'"));
  EXPECT_THAT(msg, HasSubstr("after 2 attempts"));
  EXPECT_TRUE(wait_until([&] { return fake.lines().size() == 2u; }));
}

TEST_F(SensorOnPty, SamplesCarrySensorAndHostTimeInOrder) {
  const double before = steady_now();
  std::vector<uint8_t> burst;
  for (uint16_t i = 0; i < 100; ++i) frame::append_sample(burst, sample(i, 1'000'000u + i * 5000u, static_cast<int16_t>(i), -5));
  fake.write_bytes(burst);
  for (uint16_t i = 0; i < 100; ++i) {
    auto s = sensor->next_sample(10.0);
    ASSERT_TRUE(s) << "sample " << i;
    EXPECT_EQ(s->seq, i);
    EXPECT_EQ(s->counts_alpha, i);
    EXPECT_EQ(s->counts_beta, -5);
    EXPECT_TRUE(s->valid());
    EXPECT_EQ(s->sensor_time_us, 1'000'000u + i * 5000u);
    EXPECT_DOUBLE_EQ(s->sensor_time_s, (1'000'000.0 + i * 5000.0) * 1e-6);
    EXPECT_GE(s->host_time_s, before);
    EXPECT_LE(s->host_time_s, steady_now());
  }
  auto st = sensor->stats();
  EXPECT_EQ(st.frames, 100u);
  EXPECT_EQ(st.seq_gaps, 0u);
}

TEST_F(SensorOnPty, GarbageAndBadCrcAreCountedGoodFramesSurvive) {
  std::vector<uint8_t> b{0x00, 0xFF, 0x13, 0x37, 0x5A};  // 5 bytes of line noise
  frame::append_sample(b, sample(0, 0));
  auto bad = frame::encode(sample(1, 5000));
  bad[10] ^= 0x01;
  b.insert(b.end(), bad.begin(), bad.end());
  frame::append_sample(b, sample(2, 10000));
  fake.write_bytes(b);
  auto s0 = sensor->next_sample(10.0);
  auto s2 = sensor->next_sample(10.0);
  ASSERT_TRUE(s0 && s2);
  EXPECT_EQ(s0->seq, 0);
  EXPECT_EQ(s2->seq, 2);
  auto st = sensor->stats();
  EXPECT_EQ(st.crc_errors, 1u);
  EXPECT_EQ(st.garbage_bytes, 5u + 16u);
  EXPECT_EQ(st.seq_gaps, 1u);  // the dropped frame shows as a gap
  EXPECT_EQ(st.frames_lost, 1u);
}

TEST_F(SensorOnPty, SequenceGapsAndWrapsAreCounted) {
  std::vector<uint8_t> b;
  uint16_t seqs[] = {65533, 65534, 65535, 0, 1, 5, 6};  // wrap without loss, then 3 lost
  uint32_t t = 0xFFFFF000u;
  for (uint16_t s : seqs) {
    frame::append_sample(b, sample(s, t));
    t += 5000;  // wraps the u32 clock on the way
  }
  fake.write_bytes(b);
  double last = -1;
  for (std::size_t i = 0; i < std::size(seqs); ++i) {
    auto s = sensor->next_sample(10.0);
    ASSERT_TRUE(s);
    EXPECT_EQ(s->seq, seqs[i]);
    EXPECT_GT(s->sensor_time_s, last);  // unwrapped: monotonic across the u32 wrap
    last = s->sensor_time_s;
  }
  EXPECT_DOUBLE_EQ(last, (0xFFFFF000u + 6 * 5000.0) * 1e-6);
  auto st = sensor->stats();
  EXPECT_EQ(st.seq_gaps, 1u);
  EXPECT_EQ(st.frames_lost, 3u);
}

TEST_F(SensorOnPty, RepliesAreDemultiplexedFromAStreamOfSamples) {
  fake.set_handler([&](const std::string& l) -> std::optional<std::string> {
    if (l != "TEMP?") return standard_answers(l);
    std::vector<uint8_t> b;
    for (uint16_t i = 0; i < 10; ++i) frame::append_sample(b, sample(i, i * 5000u));
    frame::append_reply(b, "TEMP -4.5");
    for (uint16_t i = 10; i < 20; ++i) frame::append_sample(b, sample(i, i * 5000u));
    fake.write_bytes(b);  // samples, reply and samples in one write
    return std::nullopt;
  });
  EXPECT_DOUBLE_EQ(sensor->temperature_c(), -4.5);
  for (uint16_t i = 0; i < 20; ++i) {
    auto s = sensor->next_sample(10.0);
    ASSERT_TRUE(s);
    EXPECT_EQ(s->seq, i);
  }
  EXPECT_EQ(sensor->stats().seq_gaps, 0u);
}

TEST_F(SensorOnPty, StaleRepliesAreNotTakenForTheAnswer) {
  fake.set_handler([&](const std::string& l) -> std::optional<std::string> {
    if (l == "ID?") {
      fake.write_frame(frame::Reply{"TEMP 20.0"});  // a late answer to an earlier command
      return "FPSS,SN=7,FW=2.0";
    }
    return standard_answers(l);
  });
  EXPECT_EQ(sensor->identify(), "FPSS,SN=7,FW=2.0");
}

TEST_F(SensorOnPty, StoppedStreamGivesNulloptAfterTheTimeout) {
  fake.write_frame(sample(0, 0));
  ASSERT_TRUE(sensor->next_sample(10.0));
  EXPECT_FALSE(sensor->next_sample(0.1));  // nothing more is coming
  EXPECT_TRUE(sensor->connected());
}

TEST_F(SensorOnPty, FlushDropsQueuedSamples) {
  std::vector<uint8_t> b;
  for (uint16_t i = 0; i < 10; ++i) frame::append_sample(b, sample(i, i * 5000u));
  fake.write_bytes(b);
  ASSERT_TRUE(wait_until([&] { return sensor->stats().frames == 10; }));
  sensor->flush();
  EXPECT_FALSE(sensor->next_sample(0.05));
  fake.write_frame(sample(10, 50000));
  auto s = sensor->next_sample(10.0);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->seq, 10);
}

// The sensor is given a link to the pty, removed at the hang-up: what disappears is the link, not
// /dev/pts/N, so another process that takes the freed pty number (ctest -j) cannot hand the
// driver's reconnect a way back.
TEST(SerialSensor, HangupWithNoWayBackEndsInDeviceError) {
  test::TempDir dir("hangup");
  test::PtyPair pty;
  FakeElectronics fake(pty.master(), standard_answers);
  const std::string link = (dir.path() / "sensor").string();
  std::filesystem::create_symlink(pty.slave_path(), link);
  auto sensor = make_sensor(options_for("pty:" + link));
  sensor->connect();
  ASSERT_TRUE(sensor->connected());
  fake.stop();
  std::filesystem::remove(link);
  pty.close_master();
  const auto msg = test::error_within<DeviceError>([&] { sensor->next_sample(0.05); });
  EXPECT_TRUE(msg.has_value());
  EXPECT_THAT(msg.value_or(""), HasSubstr("link lost"));
  EXPECT_THAT(msg.value_or(""), HasSubstr(link));
  EXPECT_FALSE(sensor->connected());
  EXPECT_THROW(sensor->identify(), DeviceError);
}

TEST(SerialSensor, QueueIsBoundedAndDropsAreCounted) {
  test::PtyPair pty;
  FakeElectronics fake(pty.master(), standard_answers);
  SensorOptions o = options_for("pty:" + pty.slave_path());
  o.max_queued_samples = 5;
  SerialSensor sensor(o);
  sensor.connect();
  std::vector<uint8_t> b;
  for (uint16_t i = 0; i < 12; ++i) frame::append_sample(b, sample(i, i * 5000u));
  fake.write_bytes(b);
  ASSERT_TRUE(wait_until([&] { return sensor.stats().frames == 12; }));
  EXPECT_EQ(sensor.stats().samples_dropped, 7u);
  EXPECT_EQ(sensor.next_sample(1.0)->seq, 7);  // the newest five are kept
}

TEST(SerialSensor, NextSampleBeforeConnectIsAnError) {
  test::PtyPair pty;
  SerialSensor sensor(options_for("pty:" + pty.slave_path()));
  EXPECT_FALSE(sensor.connected());
  EXPECT_THROW(sensor.next_sample(0.01), DeviceError);
  EXPECT_THROW(sensor.identify(), DeviceError);
}

TEST(SerialSensor, TcpTerminalServerDropIsReconnected) {
  test::TcpListener listener;
  SensorOptions o = options_for("tcp:127.0.0.1:" + std::to_string(listener.port()));
  o.reconnects = 5;
  auto sensor = make_sensor(o);
  sensor->connect();
  int first = listener.accept();
  ASSERT_GE(first, 0);
  {
    FakeElectronics fake(first, standard_answers);
    EXPECT_EQ(sensor->identify(), "FPSS,SN=0042,FW=1.3.0");
    fake.write_frame(sample(0, 0));
    ASSERT_TRUE(sensor->next_sample(10.0));
  }
  ::close(first);  // the terminal server drops the line
  int second = listener.accept();  // the driver comes back by itself
  ASSERT_GE(second, 0);
  FakeElectronics fake(second, standard_answers);
  fake.write_frame(sample(1, 5000));
  auto s = sensor->next_sample(10.0);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->seq, 1);
  EXPECT_EQ(sensor->stats().reconnects, 1u);
  EXPECT_EQ(sensor->stats().seq_gaps, 0u);
  EXPECT_DOUBLE_EQ(sensor->temperature_c(), 23.75);
  fake.stop();
  ::close(second);
}

}  // namespace
}  // namespace fpss
