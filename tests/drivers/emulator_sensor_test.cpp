// SerialSensor against the emulated sensor on a real pty: the stream, garbage, bad CRCs, a silent or stopped
// sensor; the sensor sees the Sun where ModbusGimbal points it (in process and through `fpss-stand emulate`).
#include <signal.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <map>
#include <optional>

#include "emulator_fixture.h"

using testing::HasSubstr;
namespace fpss {
namespace {

using e2e::sensor_options;
using test::error_of;
using test::wait_until;

// The published set used as the emulator's truth here: not the emulator's default (a-6-fpss1),
// so the coupling tests show that the truth file given is the one the sensor follows.
constexpr const char* kTruthSet = "a-6-fpss2";

// Reads the next sample; the emulator streams continuously, so a generous timeout never runs out.
SensorSample next(Sensor& s) {
  auto x = s.next_sample(10.0);
  if (!x) throw std::runtime_error("no sample within 10 s");
  return *x;
}


// One sample's counts inverted through the truth, against where the Sun really is.
void expect_sees(const SensorSample& s, const CoefficientSet& truth, double pitch_arcsec, double yaw_arcsec,
                 double count_noise) {
  ASSERT_TRUE(s.valid()) << "seq " << s.seq << " status " << int(s.status);
  const AxisModel a = truth.alpha_model(), b = truth.beta_model();
  EXPECT_NEAR(a.angle_arcsec(s.counts_alpha), pitch_arcsec, e2e::tolerance_arcsec(a, s.counts_alpha, count_noise))
      << "seq " << s.seq;
  EXPECT_NEAR(b.angle_arcsec(s.counts_beta), yaw_arcsec, e2e::tolerance_arcsec(b, s.counts_beta, count_noise))
      << "seq " << s.seq;
}

// ------------------------------------------------------------ manual bench clock: exact frame accounting

struct SensorOnManualBench : testing::Test {
  std::unique_ptr<Emulator> emu;
  std::unique_ptr<Sensor> sensor;
  CoefficientSet truth;
  double noise = 0;

  void SetUp() override {
    EmulatorOptions o = e2e::emulator_options();
    o.manual_clock = true;
    o.bench.serial = "E2E-0042";
    emu = std::make_unique<Emulator>(o);
    emu->start();
    truth = o.bench.truth;
    noise = o.bench.count_noise;
    sensor = make_sensor(sensor_options(emu->endpoints().sensor()));
    sensor->connect();
  }
  // Advances the bench in steps of 0.1 s, so the emulator never queues more than a few frames.
  void advance(double dt_s) {
    const double end = emu->bench_time_s() + dt_s;
    while (emu->bench_time_s() < end - 1e-9) emu->advance_to(std::min(end, emu->bench_time_s() + 0.1));
  }
  // Every frame due by the bench's current time, up to the one on the last grid point at
  // `rate_hz`, each read with a generous timeout (a quiet moment is never taken for the end).
  int rate_hz = 50;
  std::vector<SensorSample> take_due() {
    const double last_s = std::floor(emu->bench_time_s() * rate_hz + 1e-6) / rate_hz;
    const auto last_us = static_cast<uint32_t>(std::llround(last_s * 1e6));
    std::vector<SensorSample> got;
    while (got.empty() || got.back().sensor_time_us < last_us) got.push_back(next(*sensor));
    return got;
  }
  // Points the gimbal through the emulator's Modbus server (ModbusGimbal, manual clock).
  void point_gimbal(double pitch_arcsec, double yaw_arcsec) {
    ModbusGimbal g(e2e::gimbal_options(emu->endpoints().gimbal()));
    g.connect();
    g.move_to(pitch_arcsec, yaw_arcsec);
    e2e::settle_manual(*emu, g);
  }
};

TEST_F(SensorOnManualBench, CommandsAndAStreamOnTheBenchGrid) {
  EXPECT_EQ(sensor->identify(), "FPSS,SN=E2E-0042,FW=emu-1.0");
  const double t_c = emu->with_bench([](Bench& b) { return b.temperature_c(b.time_s()); });
  EXPECT_NEAR(sensor->temperature_c(), t_c, 0.005 + 1e-9);  // two decimals on the wire
  EXPECT_THROW(sensor->set_rate(500), LimitError);
  EXPECT_THAT(error_of([&] { dynamic_cast<SerialSensor&>(*sensor).command("RATE 0"); }),
              HasSubstr("'RATE 0' refused: RATE expects a whole number of Hz in 1..200"));
  sensor->set_rate(rate_hz = 100);
  sensor->start();
  advance(1.0);
  const std::vector<SensorSample> got = take_due();
  ASSERT_EQ(got.size(), 100u);
  EXPECT_FALSE(sensor->next_sample(0.2));  // exactly the 100 frames due, no more
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].seq, got[0].seq + i);
    EXPECT_EQ(got[i].sensor_time_us, got[0].sensor_time_us + 10000 * i);  // 1/RATE of bench time
    EXPECT_NEAR(got[i].sensor_time_s - got[0].sensor_time_s, 0.01 * i, 1e-9);
    expect_sees(got[i], truth, 0, 0, noise);  // the gimbal rests at zero
  }
  EXPECT_EQ(got.back().sensor_time_us, 1'000'000u);  // the grid point at bench 1 s
  const SensorStats st = sensor->stats();
  EXPECT_EQ(st.frames, 100u);
  EXPECT_EQ(st.replies, 5u);  // ID?, TEMP?, RATE 0 (ERR), RATE 100, START: RATE 500 was never sent
  EXPECT_EQ(st.crc_errors + st.garbage_bytes + st.seq_gaps + st.frames_lost, 0u);
}

TEST_F(SensorOnManualBench, GarbageBytesAreSkippedAndCountedAndSamplesStayCorrect) {
  point_gimbal(400, -300);
  sensor->start();
  advance(0.5);
  const SensorSample before = take_due().back();
  uint64_t garbage_sent = 0;
  for (int burst : {300, 17, 1000}) {
    emu->inject("sensor_garbage:bytes=" + std::to_string(burst));
    garbage_sent += static_cast<uint64_t>(burst);
    advance(0.5);
  }
  const std::vector<SensorSample> got = take_due();
  ASSERT_EQ(got.size(), 75u);  // 1.5 s at 50 Hz: not one frame swallowed by the noise
  EXPECT_EQ(emu->stats().sensor.garbage_bytes, garbage_sent);
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].seq, static_cast<uint16_t>(before.seq + 1 + i));
    expect_sees(got[i], truth, 400, -300, noise);
  }
  const SensorStats st = sensor->stats();
  EXPECT_EQ(st.garbage_bytes, garbage_sent);  // every noise byte counted, no frame byte among them
  EXPECT_EQ(st.seq_gaps, 0u);
  EXPECT_EQ(st.frames_lost, 0u);
}

TEST_F(SensorOnManualBench, BadCrcFramesAreDroppedAndCountedAndTheStreamGoesOn) {
  point_gimbal(-800, 650);
  sensor->start();
  advance(0.2);
  const SensorSample before = take_due().back();
  emu->inject("sensor_bad_crc:frames=4");
  advance(1.0);
  const std::vector<SensorSample> got = take_due();
  ASSERT_EQ(got.size(), 50u - 4u);
  EXPECT_EQ(emu->stats().sensor.bad_crc_frames, 4u);
  // The four corrupted frames are missing by seq; everything after them arrives and is right.
  EXPECT_EQ(got.front().seq, static_cast<uint16_t>(before.seq + 5));
  for (std::size_t i = 1; i < got.size(); ++i) EXPECT_EQ(got[i].seq, static_cast<uint16_t>(got[i - 1].seq + 1));
  for (const auto& s : got) expect_sees(s, truth, -800, 650, noise);
  const SensorStats st = sensor->stats();
  EXPECT_EQ(st.crc_errors, 4u);
  EXPECT_EQ(st.seq_gaps, 1u);
  EXPECT_EQ(st.frames_lost, 4u);
  EXPECT_EQ(st.garbage_bytes, 4u * 16u);  // the bytes of the four dropped frames
  EXPECT_GT(sensor->temperature_c(), -50);  // commands still answered
}

TEST_F(SensorOnManualBench, SilentSensorGivesNulloptThenResumesWithTheGapCounted) {
  sensor->start();
  advance(0.5);
  EXPECT_EQ(take_due().size(), 25u);
  emu->inject("sensor_silence:duration_s=2");
  advance(1.0);  // inside the silence
  EXPECT_FALSE(sensor->next_sample(0.3));
  {
    // A command during the silence is read and not answered: a clear error after the retries.
    auto quick = make_sensor(sensor_options(emu->endpoints().sensor(), 0.2));
    quick->connect();
    EXPECT_THAT(error_of([&] { quick->temperature_c(); }), HasSubstr("no reply to 'TEMP?' within 0.2 s after 2 attempts"));
    quick->disconnect();
  }
  EXPECT_FALSE(sensor->next_sample(0.1));
  advance(1.5);  // the silence ends at 2.5 s; frames on the grid after it flow again
  const std::vector<SensorSample> got = take_due();
  ASSERT_FALSE(got.empty());
  EXPECT_GE(got.front().sensor_time_us, 2'500'000u);  // nothing from inside the silence
  for (const auto& s : got) expect_sees(s, truth, 0, 0, noise);
  const auto emu_stats = emu->stats().sensor;
  const SensorStats st = sensor->stats();
  EXPECT_EQ(st.seq_gaps, 1u);
  EXPECT_EQ(st.frames_lost, emu_stats.frames_silenced);  // the driver accounts for every lost frame
  EXPECT_GE(emu_stats.frames_silenced, 98u);             // about 2 s at 50 Hz
  EXPECT_EQ(got.size() + emu_stats.frames_silenced, 125u);  // 0.5 s .. 3.0 s: each frame arrived or was silenced
  EXPECT_GT(sensor->temperature_c(), -50);               // answered again
}

TEST_F(SensorOnManualBench, StoppedSensorGivesNulloptUntilStartedAgain) {
  sensor->start();
  advance(0.5);
  const SensorSample last = take_due().back();
  emu->inject("sensor_stop");
  advance(1.0);
  EXPECT_FALSE(sensor->next_sample(0.3));
  const uint64_t generated = emu->stats().sensor.frames_generated;
  advance(1.0);
  EXPECT_FALSE(sensor->next_sample(0.3));
  EXPECT_EQ(emu->stats().sensor.frames_generated, generated);  // stopped, not merely silent

  // The driver closes and reopens the pty (a restarted host); then START resumes the stream.
  sensor->disconnect();
  sensor->connect();
  sensor->start();
  advance(0.5);
  const std::vector<SensorSample> got = take_due();
  ASSERT_GE(got.size(), 25u);
  EXPECT_GE(got.front().sensor_time_us, 2'500'000u);  // from the grid point after START at 2.5 s
  EXPECT_LE(got.front().sensor_time_us, 2'520'000u);
  EXPECT_EQ(got.front().seq, static_cast<uint16_t>(last.seq + 1));
  for (std::size_t i = 1; i < got.size(); ++i) EXPECT_EQ(got[i].seq, static_cast<uint16_t>(got[i - 1].seq + 1));
  for (const auto& s : got) expect_sees(s, truth, 0, 0, noise);
  EXPECT_EQ(sensor->stats().seq_gaps, 0u);  // a stopped sensor generates nothing: seq carries on
}

// ------------------------------------------------------------ real bench clock: the gimbal and the sensor coupled

// Where the gimbal was commanded, and the sensor's counts in the frames stamped after the
// gimbal reported in position (both clocks are the bench clock), inverted through the truth file.
void expect_sensor_sees_the_gimbal(Gimbal& gimbal, Sensor& sensor, const CoefficientSet& truth, double noise,
                                   double pitch_arcsec, double yaw_arcsec) {
  SCOPED_TRACE(testing::Message() << "gimbal at " << pitch_arcsec << ", " << yaw_arcsec << " arcsec");
  gimbal.move_to(pitch_arcsec, yaw_arcsec);
  const GimbalState st = gimbal.wait_in_position(60.0);
  ASSERT_TRUE(st.has(kInPosition));
  EXPECT_NEAR(st.pitch_arcsec, pitch_arcsec, 0.5);
  EXPECT_NEAR(st.yaw_arcsec, yaw_arcsec, 0.5);
  sensor.flush();
  const auto arrived_us = static_cast<uint32_t>(st.sample_time_us);  // bench time < 4294 s: no wrap
  int checked = 0;
  for (int i = 0; i < 10000 && checked < 20; ++i) {
    const SensorSample s = next(sensor);
    if (s.sensor_time_us < arrived_us) continue;  // sent while still on the way
    expect_sees(s, truth, pitch_arcsec, yaw_arcsec, noise);
    ++checked;
  }
  EXPECT_EQ(checked, 20);
}

TEST(SensorAndGimbalOnEmulator, TheSensorSeesTheSunWhereTheGimbalPointsIt) {
  test::TempDir dir("e2e");
  const auto truth_file = dir.path() / "truth.json";
  save_coefficients(truth_file, load_published(kTruthSet));
  EmulatorOptions o = e2e::emulator_options(20.0);
  o.bench.truth = load_coefficients(truth_file);
  Emulator emu(o);
  emu.start();
  auto gimbal = make_gimbal(e2e::gimbal_options(emu.endpoints().gimbal()));
  auto sensor = make_sensor(sensor_options(emu.endpoints().sensor()));
  gimbal->connect();
  sensor->connect();
  sensor->set_rate(50);
  sensor->start();

  // The inversion is through the file, read back independently of the emulator's copy.
  const CoefficientSet truth = load_coefficients(truth_file);
  for (auto [p, y] : {std::pair{0.0, 0.0}, {900.0, -600.0}, {-1500.0, 1200.0}, {1700.0, 1750.0}, {-250.5, -1699.0}})
    expect_sensor_sees_the_gimbal(*gimbal, *sensor, truth, o.bench.count_noise, p, y);

  // Not the default truth: inverted through the emulator's default set the counts would be off.
  const SensorSample s = next(*sensor);
  const double off = load_published("a-6-fpss1").alpha_model().angle_arcsec(s.counts_alpha) + 250.5;
  EXPECT_GT(std::abs(off), 1.0);

  // Beyond +-0.5 deg the Sun leaves the field of view: no sun-present bit, nothing valid.
  gimbal->move_to(2200, 0);
  const GimbalState st = gimbal->wait_in_position(60.0);
  sensor->flush();
  SensorSample out;
  do out = next(*sensor);
  while (out.sensor_time_us < static_cast<uint32_t>(st.sample_time_us));
  EXPECT_FALSE(out.status & kSunPresent);
  EXPECT_FALSE(out.valid());
  const SensorStats stats = sensor->stats();
  EXPECT_EQ(stats.crc_errors + stats.garbage_bytes, 0u);
}

// ------------------------------------------------------------ `fpss-stand emulate` as a child process

TEST(EmulateCommand, TheDriversWorkAgainstTheCommandsEndpoints) {
  test::TempDir dir("e2e");
  const auto truth_file = dir.path() / "truth.json";
  save_coefficients(truth_file, load_published(kTruthSet));
  test::Child child = test::start_emulate({"--modbus-port", "0", "--modbus-rtu", "--speed", "20", "--seed", "11",
                                          "--truth", truth_file.string(), "--unit-serial", "E2E-CHILD"},
                                         dir.path() / "stderr.txt");
  // The ready lines, in their documented order; the endpoints are taken as printed.
  std::map<std::string, std::string> ep;
  for (const char* key : {"gimbal", "gimbal-rtu", "sensor"}) {
    const auto l = child.line();
    ASSERT_TRUE(l) << "no '" << key << ":' line";
    const std::string prefix = std::string(key) + ": ";
    ASSERT_EQ(l->rfind(prefix, 0), 0u) << *l;
    ep[key] = l->substr(prefix.size());
  }
  ASSERT_EQ(child.line(), std::optional<std::string>("ready"));
  EXPECT_THAT(ep["gimbal"], testing::MatchesRegex("modbus-tcp:127\\.0\\.0\\.1:[0-9]+"));

  GimbalOptions go = e2e::gimbal_options(ep["gimbal"]);
  auto gimbal = make_gimbal(go);
  auto sensor = make_sensor(sensor_options(ep["sensor"]));
  gimbal->connect();
  sensor->connect();
  EXPECT_EQ(sensor->identify(), "FPSS,SN=E2E-CHILD,FW=emu-1.0");
  sensor->set_rate(100);
  sensor->start();
  const CoefficientSet truth = load_coefficients(truth_file);
  const double noise = default_bench_config().count_noise;
  for (auto [p, y] : {std::pair{-1100.0, 400.0}, {350.0, -1450.0}})
    expect_sensor_sees_the_gimbal(*gimbal, *sensor, truth, noise, p, y);

  // The RTU endpoint reaches the same gimbal.
  auto rtu = make_gimbal(e2e::gimbal_options(ep["gimbal-rtu"]));
  rtu->connect();
  const GimbalState s = rtu->read_state();
  EXPECT_NEAR(s.pitch_arcsec, 350, 0.5);
  EXPECT_NEAR(s.yaw_arcsec, -1450, 0.5);
  rtu->disconnect();

  sensor->stop();
  sensor->disconnect();
  gimbal->disconnect();
  child.signal(SIGTERM);
  EXPECT_EQ(child.wait(30), 0);
}

}  // namespace
}  // namespace fpss
