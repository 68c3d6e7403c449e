// Stand files: every field, the axis mapping (the paper's Table 2 geometry), and every error at file:line:column.
#include <gtest/gtest.h>

#include "base/errors.h"
#include "stand/config/stand_config.h"
#include "tests/procedures/diag_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

using test::has_errors;
using test::has_exactly;

// Parses tests/stand/expected_errors/NAME: exactly the errors its "# error@COL" comments mark.
::testing::AssertionResult errors_as_marked(const std::string& name) {
  const auto file = test::annotated_file(test::source_dir() / "tests" / "stand" / "expected_errors" / name);
  Diagnostics d(file.name);
  parse_stand(file.text, file.name, d);
  return has_exactly(d, file.errors);
}

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
  EXPECT_DOUBLE_EQ(c.sensor.temperature_min_c, -60);
  EXPECT_DOUBLE_EQ(c.sensor.temperature_max_c, 100);
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

TEST(StandConfig, EveryErrorAtOnce) { EXPECT_TRUE(errors_as_marked("every_error.yaml")); }

TEST(StandConfig, SeveralUnitsErrorsEachAtItsPlace) { EXPECT_TRUE(errors_as_marked("sensors_list.yaml")); }

TEST(StandConfig, SeveralUnitsEachWithItsSerialEndpointAndAxes) {
  Diagnostics d("s.yaml");
  const StandConfig c = parse_stand(
      "gimbal: {endpoint: 'modbus-tcp:127.0.0.1:1502'}\n"
      "sensors:\n"
      "  - {unit: FPSS1, endpoint: 'pty:/dev/pts/1', sample_rate_hz: 20}\n"
      "  - {unit: FPSS2, endpoint: 'serial:/dev/ttyUSB1:115200', axes: {pitch: beta, yaw: -alpha}, sample_rate_hz: 20,"
      " command_timeout_s: 2}\n",
      "s.yaml", d);
  ASSERT_TRUE(d.empty()) << d.text();
  ASSERT_EQ(c.units.size(), 2u);
  EXPECT_TRUE(c.multi_unit());
  EXPECT_EQ(c.units[1].serial, "FPSS2");
  EXPECT_EQ(c.units[1].axes.describe(), "pitch = +beta, yaw = -alpha");
  EXPECT_DOUBLE_EQ(c.units[1].sensor.command_timeout_s, 2);
  EXPECT_DOUBLE_EQ(c.bench.sample_rate_hz, 20);
  // Each unit's own rate, timeout and clock offset; none given: the stand's.
  EXPECT_EQ(c.units[1].sample_rate_hz, 20.0);
  EXPECT_FALSE(c.units[1].frame_timeout_s);
  Diagnostics d2("s2.yaml");
  const StandConfig two = parse_stand(
      "gimbal: {endpoint: 'modbus-tcp:127.0.0.1:1502'}\nclock: {sensor_offset_s: 0.001}\n"
      "sensors:\n"
      "  - {unit: FPSS1, endpoint: 'pty:/dev/pts/1', sample_rate_hz: 50}\n"
      "  - {unit: FPSS2, endpoint: 'pty:/dev/pts/2', sample_rate_hz: 100, frame_timeout_s: 0.5, sensor_offset_s: 0.004}\n",
      "s2.yaml", d2);
  ASSERT_TRUE(d2.empty()) << d2.text();
  EXPECT_DOUBLE_EQ(two.bench.sample_rate_hz, 50);  // the first unit's paces the dwells
  EXPECT_EQ(two.units[1].sample_rate_hz, 100.0);
  EXPECT_EQ(two.units[1].frame_timeout_s, 0.5);
  EXPECT_EQ(two.units[1].sensor_offset_s, 0.004);
  EXPECT_FALSE(two.units[0].sensor_offset_s);  // clock.sensor_offset_s
  EXPECT_DOUBLE_EQ(two.bench.sensor_time_offset_s, 0.001);
  // The first unit is also the single-unit fields.
  EXPECT_EQ(c.unit_serial, "FPSS1");
  EXPECT_EQ(c.sensor.endpoint, "pty:/dev/pts/1");
  // The single sensor: is a list of one.
  Diagnostics d1("one.yaml");
  const StandConfig one = parse_stand("gimbal: {endpoint: 'modbus-tcp:127.0.0.1:1502'}\nsensor: {endpoint: 'pty:/dev/pts/9', serial: X}\n",
                                      "one.yaml", d1);
  ASSERT_TRUE(d1.empty()) << d1.text();
  ASSERT_EQ(one.units.size(), 1u);
  EXPECT_EQ(one.units[0].serial, "X");
  EXPECT_FALSE(one.multi_unit());
}

TEST(StandConfig, NumbersOutsideTheirRangeNamePlaceAndField) {
  EXPECT_TRUE(errors_as_marked("numbers_out_of_range.yaml"));
}

// The missing devices are reported at the document's start, once each.
TEST(StandConfig, MissingDevicesAndBadMapping) { EXPECT_TRUE(errors_as_marked("missing_devices.yaml")); }

TEST(StandConfig, TemperatureRangeDefaultsAndIsTakenFromTheSensorBlock) {
  Diagnostics d("t.yaml");
  const std::string head = "gimbal: {endpoint: 'modbus-tcp:h:1'}\n";
  StandConfig c = parse_stand(head + "sensor: {endpoint: 'tcp:h:2'}\n", "t.yaml", d);
  ASSERT_TRUE(d.empty()) << d.text();
  EXPECT_DOUBLE_EQ(c.sensor.temperature_min_c, -60);
  EXPECT_DOUBLE_EQ(c.sensor.temperature_max_c, 100);
  c = parse_stand(head + "sensor: {endpoint: 'tcp:h:2', temperature_range_c: [-20.5, 45]}\n", "t.yaml", d);
  ASSERT_TRUE(d.empty()) << d.text();
  EXPECT_DOUBLE_EQ(c.sensor.temperature_min_c, -20.5);
  EXPECT_DOUBLE_EQ(c.sensor.temperature_max_c, 45);
  EXPECT_EQ(to_json(c)["sensor"]["temperature_range_c"], nlohmann::json::array({-20.5, 45}));
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
