// Stand files: every field, the axis mapping (the paper's Table 2 geometry), and every error at file:line:column.
#include <gtest/gtest.h>

#include "calib/errors.h"
#include "stand/config/stand_config.h"
#include "tests/procedures/diag_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

using test::file_expecting;
using test::has_errors;
using test::has_exactly;

TEST(StandConfig, ExampleStandFile) {
  const StandConfig c = load_stand_file(test::source_dir() / "procedures" / "example_stand.yaml");
  EXPECT_EQ(c.stand_id, "lab-bench-1");
  EXPECT_EQ(c.unit_serial, "FPSS1-SN042");
  EXPECT_EQ(c.gimbal.endpoint, "modbus-tcp:192.168.10.20:502");
  EXPECT_EQ(c.sensor.endpoint, "serial:/dev/ttyUSB0:115200");
  EXPECT_EQ(c.gimbal.retries, 3);
  EXPECT_DOUBLE_EQ(c.bench.limits.pitch_min_arcsec, -2700);
  EXPECT_DOUBLE_EQ(c.bench.limits.yaw_max_arcsec, 2700);
  EXPECT_DOUBLE_EQ(c.gimbal.limits.pitch_max_arcsec, 2700);  // the driver enforces the same limits
  EXPECT_DOUBLE_EQ(c.bench.sample_rate_hz, 50);
  EXPECT_DOUBLE_EQ(c.bench.watchdog_s, 2);
  EXPECT_EQ(c.bench.clock, ClockSync::host);
  EXPECT_EQ(c.bench.max_remeasure, 3);
  EXPECT_EQ(c.bench.axes.describe(), "pitch = +beta, yaw = -alpha");
}

TEST(StandConfig, Table2MappingGivesSensorFrameReferences) {
  Diagnostics d("s.yaml");
  StandConfig c = parse_stand("gimbal: {endpoint: 'modbus-tcp:127.0.0.1:1502'}\nsensor: {endpoint: 'pty:/dev/pts/9'}\n"
                              "axes: {pitch: beta, yaw: -alpha}\n",
                              "s.yaml", d);
  ASSERT_TRUE(d.empty()) << d.text();
  // Gimbal at pitch +100, yaw +200: the sensor's beta sees +100, its alpha sees -200.
  auto [alpha, beta] = c.bench.axes.sensor_from_stand(100, 200);
  EXPECT_DOUBLE_EQ(alpha, -200);
  EXPECT_DOUBLE_EQ(beta, 100);
  auto [p, y] = c.bench.axes.stand_from_sensor(alpha, beta);
  EXPECT_DOUBLE_EQ(p, 100);
  EXPECT_DOUBLE_EQ(y, 200);
  // Default: alpha -> pitch, beta -> yaw.
  AxisMapping def;
  EXPECT_EQ(def.sensor_from_stand(100, 200), (std::pair<double, double>{100, 200}));
}

TEST(StandConfig, EveryErrorAtOnce) {
  const auto file = file_expecting({
      {"stand: x"},
      {"gimbal:"},
      {"  endpoint: serial:/dev/ttyUSB0", {{13, "is a serial endpoint; expected modbus-tcp"}}},
      {"  retries: many", {{12, "field retries: expected an integer, got \"many\""}}},
      {"sensor:"},
      {"  endpoint: pty", {{13, "sensor: field endpoint:"}}},
      {"  sample_rate_hz: 500", {{19, "expected an integer in 1..200"}}},
      {"soft_limits:"},
      {"  pitch_deg: [0.5, -0.5]", {{14, "expected min < max"}}},
      {"  roll_deg: [-1, 1]", {{3, "unknown field \"roll_deg\""}}},
      {"axes: {pitch: alpha, yaw: alpha}", {{7, "pitch and yaw both map to alpha"}}},
      {"colour: red", {{1, "unknown field \"colour\""}}},
  });
  Diagnostics d("stand.yaml");
  parse_stand(file.text, "stand.yaml", d);
  EXPECT_TRUE(has_exactly(d, file.errors));
}

TEST(StandConfig, NumbersOutsideTheirRangeNamePlaceAndField) {
  const auto file = file_expecting({
      {"gimbal:"},
      {"  endpoint: 'modbus-tcp:127.0.0.1:1502'"},
      {"  response_timeout_s: 1e308", {{23, "field response_timeout_s: 1e308 is outside [-86400, 86400]"}}},
      {"  profile_rate_arcsec_s: 1e9", {{26, "field profile_rate_arcsec_s: 1e9 is outside [-360000, 360000]"}}},
      {"sensor: {endpoint: 'pty:/dev/pts/9'}"},
      {"soft_limits:"},
      {"  pitch_deg: [-1e6, 0.75]", {{15, "-1e6 is outside [-180, 180]"}}},
      {"clock:"},
      {"  sensor_offset_s: -1e300", {{20, "field sensor_offset_s: -1e300 is outside"}}},
  });
  Diagnostics d("s.yaml");
  parse_stand(file.text, "s.yaml", d);
  EXPECT_TRUE(has_errors(d, file.errors));
}

TEST(StandConfig, MissingDevicesAndBadMapping) {
  // The missing devices are reported at the document's start.
  const auto file = file_expecting({
      {"axes: {pitch: gamma}",
       {{1, "missing field gimbal"}, {1, "missing field sensor"}, {15, "expected alpha, beta, +alpha"}}},
      {"soft_limits: {yaw_arcsec: [100, 200]}", {{14, "must contain the null"}}},
  });
  Diagnostics d("s.yaml");
  parse_stand(file.text, "s.yaml", d);
  EXPECT_TRUE(has_errors(d, file.errors));
}

TEST(StandConfig, ProfileRateAboveTheLimit) {
  Diagnostics d("s.yaml");
  parse_stand("gimbal: {endpoint: 'modbus-tcp:h:1', profile_rate_deg_s: 2}\nsensor: {endpoint: 'tcp:h:2'}\n"
              "soft_limits: {max_rate_deg_s: 1}\n",
              "s.yaml", d);
  ASSERT_EQ(d.size(), 1u) << d.text();
  EXPECT_NE(d.text().find("profile rate 7200 arcsec/s is above soft_limits max rate 3600"), std::string::npos);
}

TEST(StandConfig, LoadThrowsInputError) {
  test::TempDir tmp("stand");
  test::write_file(tmp / "s.yaml", "gimbal: [1, 2]\n");
  EXPECT_THROW(load_stand_file(tmp / "s.yaml"), InputError);
  EXPECT_THROW(load_stand_file(tmp / "missing.yaml"), InputError);
}

TEST(StandConfig, EmulatedStand) {
  StandConfig c = emulated_stand(50);
  EXPECT_EQ(c.bench.clock, ClockSync::shared);
  EXPECT_DOUBLE_EQ(c.bench.time_scale, 50);
  EXPECT_DOUBLE_EQ(c.bench.wall(5.0), 0.1);
}

}  // namespace
}  // namespace fpss
