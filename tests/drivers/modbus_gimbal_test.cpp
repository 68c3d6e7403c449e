// ModbusGimbal against a real libmodbus server on loopback (and RTU on a real pty): encoding, limits, errors, retries.
#include "drivers/modbus_gimbal.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <modbus.h>

#include "drivers/endpoints.h"
#include "modbus_test_server.h"
#include "test_util.h"
#include "tests/drivers/driver_options.h"

using fpss::test::ModbusTestServer;
using testing::HasSubstr;
using Action = ModbusTestServer::Action;
namespace fpss {
namespace {

using test::error_of;

// A server and a gimbal with the default options connected to it.
class ConnectedModbusGimbal : public testing::Test {
 protected:
  void SetUp() override { g.connect(); }
  ModbusTestServer server;
  ModbusGimbal g{e2e::gimbal_options(server.endpoint())};
};

// Each of `parts` is in the message.
void expect_mentions(const std::string& message, std::initializer_list<const char*> parts) {
  for (const char* part : parts) EXPECT_THAT(message, HasSubstr(part));
}

int count_function(const std::vector<ModbusTestServer::Request>& rs, int fc) {
  int n = 0;
  for (const auto& r : rs) n += r.function == fc;
  return n;
}

TEST(ModbusGimbal, ConstructorTouchesNoHardware) {
  ModbusTestServer server;
  ModbusGimbal g(e2e::gimbal_options(server.endpoint()));
  EXPECT_FALSE(g.connected());
  EXPECT_EQ(server.connections(), 0);
  EXPECT_THAT(error_of([&] { g.read_state(); }), HasSubstr("before connect()"));
  g.connect();
  EXPECT_TRUE(g.connected());
  g.read_state();
  EXPECT_EQ(server.connections(), 1);
}

TEST(ModbusGimbal, ReadStateDecodesNegativeAnglesAndU64TimeInOneRequest) {
  ModbusTestServer server;
  server.set_input_i32(0, -1'234'567);  // pitch -1234.567 arcsec
  server.set_input_i32(2, 7'000'001);
  server.set_input_i32(4, -1);
  server.set_input_i32(6, 2'000'000);
  server.set_input(8, kHomed | kInPosition | kRateMode);
  server.set_input(9, 0);
  server.set_input_u64(10, 0x0123'4567'89AB'CDEFull);
  server.set_input(14, 65535);
  ModbusGimbal g(e2e::gimbal_options(server.endpoint()));
  g.connect();
  GimbalState s = g.read_state();
  EXPECT_DOUBLE_EQ(s.pitch_arcsec, -1234.567);
  EXPECT_DOUBLE_EQ(s.yaw_arcsec, 7000.001);
  EXPECT_DOUBLE_EQ(s.pitch_rate_arcsec_s, -0.001);
  EXPECT_DOUBLE_EQ(s.yaw_rate_arcsec_s, 2000.0);
  EXPECT_TRUE(s.has(kHomed));
  EXPECT_TRUE(s.has(kRateMode));
  EXPECT_FALSE(s.has(kMoving));
  EXPECT_EQ(s.sample_time_us, 0x0123'4567'89AB'CDEFull);
  EXPECT_EQ(s.moves_completed, 65535);
  EXPECT_GT(s.host_time_s, 0);
  auto rs = server.requests();
  ASSERT_EQ(rs.size(), 1u);
  EXPECT_EQ(rs[0].function, MODBUS_FC_READ_INPUT_REGISTERS);
  EXPECT_EQ(rs[0].addr, 0);
  EXPECT_EQ(rs[0].count, 15);
}

TEST(ModbusGimbal, MoveWritesTargetsWithFunction16ThenCommand1AndWaits) {
  ModbusTestServer server;
  server.set_move_reads(3);
  ModbusGimbal g(e2e::gimbal_options(server.endpoint()));
  g.connect();
  g.move_to(-1000.5, 2000.25);
  auto rs = server.requests();
  ASSERT_EQ(rs.size(), 2u);
  EXPECT_EQ(rs[0].function, MODBUS_FC_WRITE_MULTIPLE_REGISTERS);
  EXPECT_EQ(rs[0].addr, 0);
  EXPECT_EQ(rs[0].count, 4);
  uint16_t expect[4];
  put_i32(expect, -1'000'500);
  put_i32(expect + 2, 2'000'250);
  EXPECT_EQ(rs[0].values, std::vector<uint16_t>(expect, expect + 4));
  EXPECT_EQ(rs[1].function, MODBUS_FC_WRITE_SINGLE_REGISTER);
  EXPECT_EQ(rs[1].addr, 11);
  EXPECT_EQ(rs[1].values, std::vector<uint16_t>{1});
  EXPECT_EQ(server.holding_i32(0), -1'000'500);

  GimbalState s = g.wait_in_position(30.0);
  EXPECT_DOUBLE_EQ(s.pitch_arcsec, -1000.5);
  EXPECT_DOUBLE_EQ(s.yaw_arcsec, 2000.25);
  EXPECT_TRUE(s.has(kInPosition));
  EXPECT_FALSE(s.has(kMoving));
  EXPECT_EQ(s.moves_completed, 1);
  // Three reads saw "moving", the fourth the arrival.
  EXPECT_EQ(count_function(server.requests(), MODBUS_FC_READ_INPUT_REGISTERS), 4);
}

TEST_F(ConnectedModbusGimbal, SoftLimitsRefuseBeforeAnythingIsSent) {
  std::string msg = error_of([&] { g.move_to(3000, 0); });
  expect_mentions(msg, {"pitch", "3000", "2700"});
  EXPECT_THROW(g.move_to(0, -2700.001), LimitError);
  EXPECT_THAT(error_of([&] { g.move_to(0, -2700.001); }), HasSubstr("yaw"));
  EXPECT_THROW(g.move_to(std::nan(""), 0), LimitError);
  EXPECT_THROW(g.set_max_rate(3600.5), LimitError);
  EXPECT_THROW(g.set_max_rate(0), LimitError);
  EXPECT_THROW(g.start_rate(0, -4000), LimitError);
  EXPECT_THROW(g.set_watchdog(-1), LimitError);
  EXPECT_THROW(g.set_watchdog(70), LimitError);
  EXPECT_EQ(server.writes_seen(), 0u);
  EXPECT_TRUE(server.requests().empty());
  // The limits themselves are allowed.
  g.move_to(2700, -2700);
  EXPECT_EQ(server.writes_seen(), 2u);
}

TEST(ModbusGimbal, Exception03NamesTheRegistersAndIsNotRetried) {
  ModbusTestServer server;
  GimbalOptions o = e2e::gimbal_options(server.endpoint());
  o.limits.pitch_max_arcsec = 10'000;  // soft limits wider than the device's hard limits
  ModbusGimbal g(o);
  g.connect();
  std::string msg = error_of([&] { g.move_to(8000, 0); });
  expect_mentions(msg, {"holding registers 0..3", "pitch_target_mas", "exception 03", "function 16"});
  auto rs = server.requests();
  ASSERT_EQ(rs.size(), 1u);  // not retried, and no move command after the refused targets
  EXPECT_EQ(g.counters().retries, 0u);
  EXPECT_TRUE(g.connected());  // an exception is an answer: the link stays up
}

TEST_F(ConnectedModbusGimbal, Exception02NamesTheUnmappedAddress) {
  std::string msg = error_of([&] { g.read_input_registers(20, 2); });
  expect_mentions(msg, {"input registers 20..21", "exception 02", "not mapped"});
  EXPECT_EQ(server.requests().size(), 1u);
  msg = error_of([&] { g.write_holding_registers(13, {1}); });
  expect_mentions(msg, {"holding register 13", "exception 02"});
}

TEST_F(ConnectedModbusGimbal, UnknownCommandIsException03OnTheCommandRegister) {
  std::string msg = error_of([&] { g.write_holding_registers(11, {9}); });
  expect_mentions(msg, {"holding register 11 (command)", "exception 03"});
}

TEST(ModbusGimbal, TimeoutsAreRetriedOnAFreshConnectionThenSucceed) {
  ModbusTestServer server;
  server.set_hook([](const ModbusTestServer::Request&, std::size_t i) {
    return ModbusTestServer::Decision{i < 2 ? Action::drop : Action::reply, 0};
  });
  ModbusGimbal g(e2e::gimbal_options(server.endpoint(), 1.0));
  g.connect();
  server.set_input_i32(0, 42'000);
  EXPECT_DOUBLE_EQ(g.read_state().pitch_arcsec, 42.0);
  EXPECT_EQ(g.counters().retries, 2u);
  EXPECT_EQ(g.counters().reconnects, 2u);
  EXPECT_EQ(server.connections(), 3);
  EXPECT_EQ(server.requests().size(), 3u);
}

TEST(ModbusGimbal, PersistentTimeoutEndsInAClearError) {
  ModbusTestServer server;
  server.set_hook([](const ModbusTestServer::Request&, std::size_t) {
    return ModbusTestServer::Decision{Action::drop, 0};
  });
  ModbusGimbal g(e2e::gimbal_options(server.endpoint(), 1.0));
  g.connect();
  std::string msg = error_of([&] { g.read_state(); });
  expect_mentions(msg, {"input registers 0..14", "after 3 attempts", "timed out", "errno 110"});
  EXPECT_EQ(server.requests().size(), 3u);
  // Safe state: the driver dropped the link; the next request starts from a fresh one.
  EXPECT_FALSE(g.connected());
  server.set_hook(nullptr);
  g.read_state();
  EXPECT_TRUE(g.connected());
}

TEST(ModbusGimbal, AReplyDribbledByteByByteIsATimeoutWithinTheDeadline) {
  ModbusTestServer server;
  server.set_hook([](const ModbusTestServer::Request&, std::size_t) {
    return ModbusTestServer::Decision{Action::dribble, 0, 0.1};  // 39 bytes: 3.9 s for one reply
  });
  GimbalOptions o = e2e::gimbal_options(server.endpoint(), 0.5);
  o.retries = 2;
  ModbusGimbal g(o);
  g.connect();
  const auto t0 = std::chrono::steady_clock::now();
  const std::string msg = error_of([&] { g.read_state(); });
  const double took_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  expect_mentions(msg, {"input registers 0..14", "after 3 attempts", "errno 110"});
  EXPECT_EQ(g.counters().retries, 2u);
  // Each attempt ends within twice the response timeout, so three attempts and two backoffs stay
  // below the time the device takes to send even one reply (libmodbus alone: 3 x 3.9 s).
  EXPECT_LT(took_s, 3.9);
  std::printf("dribbled reply: gave up after %.3f s (3 attempts)\n", took_s);

  // A reply dribbled fast enough to be complete within the response timeout is taken.
  server.set_hook([](const ModbusTestServer::Request&, std::size_t) {
    return ModbusTestServer::Decision{Action::dribble, 0, 0.001};
  });
  GimbalOptions patient = e2e::gimbal_options(server.endpoint(), 2.0);
  ModbusGimbal g2(patient);
  g2.connect();
  server.set_input_i32(0, 42'000);
  EXPECT_DOUBLE_EQ(g2.read_state().pitch_arcsec, 42.0);
}

TEST(ModbusGimbal, DroppedConnectionIsReconnected) {
  ModbusTestServer server;
  server.set_hook([](const ModbusTestServer::Request&, std::size_t i) {
    return ModbusTestServer::Decision{i == 1 ? Action::close : Action::reply, 0};
  });
  ModbusGimbal g(e2e::gimbal_options(server.endpoint()));
  g.connect();
  g.read_state();
  server.set_input_i32(2, -5'000);
  EXPECT_DOUBLE_EQ(g.read_state().yaw_arcsec, -5.0);  // the server hung up on this one
  EXPECT_EQ(g.counters().reconnects, 1u);
  EXPECT_EQ(g.counters().retries, 1u);
  EXPECT_EQ(server.connections(), 2);
}

TEST(ModbusGimbal, BusyIsRetriedOtherExceptionsAreNot) {
  ModbusTestServer server;
  server.set_hook([](const ModbusTestServer::Request&, std::size_t i) {
    return ModbusTestServer::Decision{i == 0 ? Action::exception : Action::reply, MODBUS_EXCEPTION_SLAVE_OR_SERVER_BUSY};
  });
  ModbusGimbal g(e2e::gimbal_options(server.endpoint()));
  g.connect();
  g.read_state();
  EXPECT_EQ(g.counters().retries, 1u);
  EXPECT_EQ(server.connections(), 1);  // busy is an answer: same connection

  server.set_hook([](const ModbusTestServer::Request&, std::size_t) {
    return ModbusTestServer::Decision{Action::exception, MODBUS_EXCEPTION_SLAVE_OR_SERVER_FAILURE};
  });
  std::string msg = error_of([&] { g.read_state(); });
  EXPECT_THAT(msg, HasSubstr("exception 04"));
  EXPECT_EQ(g.counters().retries, 1u);
}

TEST(ModbusGimbal, NoServerGivesConnectionRefusedWithErrno) {
  test::RefusingPort refusing;
  GimbalOptions o = e2e::gimbal_options("modbus-tcp:127.0.0.1:" + std::to_string(refusing.port()));
  ModbusGimbal g(o);
  std::string msg = error_of([&] { g.connect(); });
  expect_mentions(msg, {"cannot connect", "errno 111", "after 3 attempts"});
  EXPECT_FALSE(g.connected());
}

TEST(ModbusGimbal, FaultWhileWaitingNamesTheFaultCode) {
  ModbusTestServer server;
  server.set_fault_on_move(static_cast<uint16_t>(GimbalFault::following_error));
  ModbusGimbal g(e2e::gimbal_options(server.endpoint()));
  g.connect();
  g.move_to(10, 10);
  std::string msg = error_of([&] { g.wait_in_position(30.0); });
  expect_mentions(msg, {"fault 1 (following_error)", "input register 9"});
  g.clear_fault();
  EXPECT_EQ(g.read_state().fault, GimbalFault::none);
}

TEST(ModbusGimbal, WaitInPositionTimesOutWhileStillMoving) {
  ModbusTestServer server;
  server.set_move_reads(1'000'000);
  GimbalOptions o = e2e::gimbal_options(server.endpoint());
  o.poll_interval_s = 0.01;
  ModbusGimbal g(o);
  g.connect();
  g.move_to(100, 0);
  std::string msg = error_of([&] { g.wait_in_position(0.1); });
  expect_mentions(msg, {"not in position within 0.1 s", "still moving"});
}

TEST_F(ConnectedModbusGimbal, RateMaxRateAndWatchdogRegisters) {
  g.set_max_rate(3000.5);
  EXPECT_EQ((static_cast<uint32_t>(server.holding(8)) << 16) | server.holding(9), 3'000'500u);
  g.set_watchdog(2.5);
  EXPECT_EQ(server.holding(12), 2500);
  g.start_rate(-12.5, 30);
  EXPECT_EQ(server.holding_i32(4), -12'500);
  EXPECT_EQ(server.holding_i32(6), 30'000);
  EXPECT_EQ(server.holding(11), 5);
  GimbalState s = g.read_state();
  EXPECT_TRUE(s.has(kRateMode));
  EXPECT_DOUBLE_EQ(s.pitch_rate_arcsec_s, -12.5);
  g.stop();
  EXPECT_EQ(server.holding(11), 2);
  EXPECT_FALSE(g.read_state().has(kRateMode));
  g.home();
  EXPECT_EQ(server.holding(11), 3);
  auto h = g.read_holding_registers(0, 13);
  EXPECT_EQ(h[12], 2500);
}

TEST(ModbusGimbal, RtuOverARealPty) {
  ModbusTestServer server(ModbusTestServer::Transport::rtu_pty);
  server.set_input_i32(0, -900'000);
  server.set_input_u64(10, 123'456'789'012ull);
  auto gimbal = make_gimbal(e2e::gimbal_options(server.endpoint()));
  gimbal->connect();
  GimbalState s = gimbal->read_state();
  EXPECT_DOUBLE_EQ(s.pitch_arcsec, -900.0);
  EXPECT_EQ(s.sample_time_us, 123'456'789'012ull);
  gimbal->move_to(-100, 50);
  EXPECT_DOUBLE_EQ(gimbal->wait_in_position(30).yaw_arcsec, 50.0);
}

TEST(ModbusGimbal, FactoryRefusesNonModbusEndpoints) {
  GimbalOptions o;
  o.endpoint = "pty:/dev/pts/3";
  EXPECT_THROW(make_gimbal(o), EndpointError);
  o.endpoint = "modbus-tcp:localhost";
  EXPECT_THAT(error_of([&] { make_gimbal(o); }), HasSubstr("modbus-tcp:localhost"));
  o.endpoint = "modbus-tcp:127.0.0.1:1502";
  EXPECT_NE(dynamic_cast<ModbusGimbal*>(make_gimbal(o).get()), nullptr);
}

}  // namespace
}  // namespace fpss
