// The engine's clock on a host-clock stand: when a frame was taken, from the sensor's own stamps.
#include <gtest/gtest.h>

#include "procedures/engine_clock.h"

namespace fpss {
namespace {

SensorSample frame(double sensor_s, double host_s) {
  SensorSample f;
  f.sensor_time_s = sensor_s;
  f.host_time_s = host_s;
  return f;
}

// An emulator at 50x: the sensor's stamps run 50 times the host's clock; the link delays each frame
// by 2 ms, until the stream stalls and a burst of frames taken during the move arrives at once.
TEST(EngineClock, AFrameOfALateBurstIsTakenWhenItWasStampedNotWhenItCame) {
  EngineSettings b;
  b.time_scale = 50;
  EngineClock clock(b);
  for (int i = 0; i < 10; ++i) {  // a frame every 0.02 s of bench time, 0.4 ms of host time
    const SensorSample f = frame(100 + 0.02 * i, 10 + 0.0004 * i + 0.002);
    clock.note_sensor_frame(f);
    EXPECT_NEAR(clock.taken_host_s(f), f.host_time_s, 1e-9);  // on time: taken when it came, less nothing
  }
  // Stamped 1.5 s of bench time later (0.03 s of host time), received 0.5 s of host time late.
  const SensorSample late = frame(101.5, 10.03 + 0.002 + 0.5);
  clock.note_sensor_frame(late);
  // Its stamp in host time plus the link's 2 ms, and the drift allowance since the last frame (100 ppm).
  EXPECT_NEAR(clock.taken_host_s(late), 10.032 + 1e-4 * (late.host_time_s - (10 + 0.0036 + 0.002)), 1e-9);
  EXPECT_LT(clock.taken_host_s(late), late.host_time_s);
}

TEST(EngineClock, ARestartedSensorClockStartsTheLinkDelayAgain) {
  EngineSettings b;
  EngineClock clock(b);
  clock.note_sensor_frame(frame(500, 20.001));
  const SensorSample restarted = frame(0.1, 30.001);  // its clock began again at 0
  clock.note_sensor_frame(restarted);
  EXPECT_NEAR(clock.taken_host_s(restarted), restarted.host_time_s, 1e-9);
}

TEST(EngineClock, BeforeAnyFrameTheReceiptIsAllItKnows) {
  EngineSettings b;
  EngineClock clock(b);
  EXPECT_EQ(clock.taken_host_s(frame(5, 7)), 7);
}

}  // namespace
}  // namespace fpss
