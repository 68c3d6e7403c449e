// ModbusGimbal against the emulated gimbal over real loopback TCP (and RTU on a real pty): moves, and every
// gimbal-side fault of docs/emulator.md ending in a successful retry or a clear error and a safe state.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>

#include "emulator_fixture.h"

using testing::HasSubstr;
namespace fpss {
namespace {

using e2e::bench_gimbal;
using e2e::bench_targets;
using e2e::gimbal_options;
using test::error_of;
using test::wait_until;

struct GimbalOnEmulator : testing::Test {
  std::unique_ptr<Emulator> emu;
  std::unique_ptr<ModbusGimbal> gimbal;

  void start(EmulatorOptions o = e2e::emulator_options(), double response_timeout_s = 5.0) {
    emu = std::make_unique<Emulator>(std::move(o));
    emu->start();
    gimbal = std::make_unique<ModbusGimbal>(gimbal_options(emu->endpoints().gimbal(), response_timeout_s));
    gimbal->connect();
  }
  uint64_t requests() { return emu->stats().modbus_tcp.requests; }
  // A move that must finish: through the driver, in position and not moving, at the target.
  GimbalState move_and_wait(double pitch_arcsec, double yaw_arcsec) {
    gimbal->move_to(pitch_arcsec, yaw_arcsec);
    GimbalState s = gimbal->wait_in_position(60.0);
    EXPECT_TRUE(s.has(kInPosition));
    EXPECT_FALSE(s.has(kMoving));
    EXPECT_EQ(s.fault, GimbalFault::none);
    // Window 0.1 arcsec plus encoder noise (0.05 arcsec, 1 sigma) and 1 mas resolution.
    EXPECT_NEAR(s.pitch_arcsec, pitch_arcsec, 0.5);
    EXPECT_NEAR(s.yaw_arcsec, yaw_arcsec, 0.5);
    return s;
  }
  // A read right after a fault injected on the link: answered, after a retry on a fresh link.
  void expect_read_recovers_on_a_fresh_link() {
    EXPECT_EQ(gimbal->read_state().fault, GimbalFault::none);
    EXPECT_GE(gimbal->counters().retries, 1u);
    EXPECT_GE(gimbal->counters().reconnects, 1u);
  }
};

TEST_F(GimbalOnEmulator, MoveCompletesInPositionThroughTheDriver) {
  start();
  GimbalState s0 = gimbal->read_state();
  EXPECT_EQ(s0.fault, GimbalFault::none);
  EXPECT_TRUE(s0.has(kInPosition));
  EXPECT_EQ(bench_targets(*emu), (e2e::Targets{0, 0}));

  gimbal->set_max_rate(900);
  GimbalState s = move_and_wait(1234.567, -876.5);
  // Exactly what the driver wrote, in mas, reached the emulator's target registers.
  EXPECT_EQ(bench_targets(*emu), (e2e::Targets{1234.567, -876.5}));
  EXPECT_EQ(gimbal->read_holding_registers(gimbal_reg::kMaxRateMasS, 2), (std::vector<uint16_t>{900'000 >> 16, 900'000 & 0xFFFF}));
  EXPECT_EQ(s.moves_completed, static_cast<uint16_t>(s0.moves_completed + 1));
  EXPECT_GT(s.sample_time_us, s0.sample_time_us);  // the bench clock, through the driver

  // A second move the other way; the noiseless truth agrees with what the driver read.
  move_and_wait(-2000, 1500);
  const GimbalReadout truth = bench_gimbal(*emu);
  EXPECT_NEAR(truth.pitch_arcsec, -2000, 0.1);
  EXPECT_NEAR(truth.yaw_arcsec, 1500, 0.1);
  EXPECT_EQ(gimbal->counters().retries, 0u);
  EXPECT_EQ(gimbal->counters().reconnects, 0u);
}

// An emulator on the end-to-end options with `configure` applied, started.
std::unique_ptr<Emulator> started_emulator(const std::function<void(EmulatorOptions&)>& configure) {
  EmulatorOptions o = e2e::emulator_options();
  configure(o);
  auto emu = std::make_unique<Emulator>(o);
  emu->start();
  return emu;
}

// A scheduled move through the driver (a stand that says timed_moves): the targets, the start
// on the gimbal's clock and command 6; the gimbal holds with move_pending until its clock reaches
// the start, then moves, and arrives when its profile says from that instant. A start already past
// is refused, and a gimbal the stand does not say has them is never sent one.
TEST(GimbalOnEmulatorClock, AScheduledMoveStartsWhenTheGimbalsClockSays) {
  const auto owned = started_emulator([](EmulatorOptions& o) { o.manual_clock = true; });
  Emulator& emu = *owned;
  GimbalOptions go = gimbal_options(emu.endpoints().gimbal(), 5.0);
  go.timed_moves = true;
  ModbusGimbal g(go);
  g.connect();
  ASSERT_TRUE(g.timed_moves());
  emu.advance_to(2.0);
  g.move_at(-720.0, 360.0, 3'250'000);
  GimbalState s = g.read_state();
  EXPECT_TRUE(s.has(kMovePending));
  EXPECT_FALSE(s.has(kMoving));
  EXPECT_EQ(g.read_command()->command, gimbal_reg::kCmdMoveAt);
  EXPECT_EQ(g.read_holding_registers(gimbal_reg::kMoveAtUs, 4), (std::vector<uint16_t>{0, 0, 0x0031, 0x9750}));
  emu.advance_to(3.249);
  EXPECT_NEAR(g.read_state().pitch_arcsec, 0.0, 0.5);
  emu.advance_to(3.3);
  s = g.read_state();
  EXPECT_FALSE(s.has(kMovePending));
  EXPECT_TRUE(s.has(kMoving));
  EXPECT_LT(s.pitch_arcsec, 0.0);
  emu.advance_to(10.0);
  EXPECT_NEAR(emu.with_bench([](Bench& b) { return b.last_arrival_s(); }) - 3.25, 2 * std::sqrt(720.0 / 3600.0), 0.025);
  EXPECT_THAT(error_of([&] { g.move_at(0, 0, 9'000'000); }), HasSubstr("exception 03"));

  ModbusGimbal plain(gimbal_options(emu.endpoints().gimbal(), 5.0));
  plain.connect();
  EXPECT_FALSE(plain.timed_moves());
  const uint64_t before = emu.stats().modbus_tcp.requests;
  EXPECT_THROW(plain.move_at(0, 0, 20'000'000), DeviceError);
  EXPECT_EQ(emu.stats().modbus_tcp.requests, before);
}

TEST_F(GimbalOnEmulator, DroppedConnectionIsReconnectedAndTheNextReadAndMoveSucceed) {
  start();
  gimbal->read_state();
  const auto conns0 = emu->stats().modbus_tcp.connections;

  // The emulator closes the TCP connection instead of answering the read.
  emu->inject("modbus_drop");
  expect_read_recovers_on_a_fresh_link();
  EXPECT_EQ(emu->stats().modbus_tcp.dropped, 1u);
  EXPECT_GT(emu->stats().modbus_tcp.connections, conns0);  // a new TCP connection, not a reused one
  EXPECT_TRUE(gimbal->connected());

  // A drop in the middle of a move: the target write is lost with the connection, sent again on
  // the new one, and the move completes.
  emu->inject("modbus_drop");
  move_and_wait(600, -300);
  EXPECT_EQ(emu->stats().modbus_tcp.dropped, 2u);
  EXPECT_EQ(bench_targets(*emu), (e2e::Targets{600, -300}));
  EXPECT_GE(gimbal->counters().reconnects, 2u);
}

TEST_F(GimbalOnEmulator, DropsBeyondTheRetryBudgetEndInAClearErrorAndTheLinkRecovers) {
  start();
  const int attempts = gimbal->options().retries + 1;
  emu->inject("modbus_drop:count=" + std::to_string(attempts));
  const std::string e = error_of([&] { gimbal->read_state(); });
  EXPECT_THAT(e, HasSubstr("gimbal " + emu->endpoints().gimbal()));
  EXPECT_THAT(e, HasSubstr("input registers 0..14 (pitch_position_mas..moves_completed)"));
  EXPECT_THAT(e, HasSubstr("failed after " + std::to_string(attempts) + " attempts"));
  EXPECT_THAT(e, HasSubstr("errno"));
  EXPECT_EQ(emu->stats().modbus_tcp.dropped, static_cast<uint64_t>(attempts));
  // Safe state: nothing moved, and the next call reconnects and succeeds.
  EXPECT_FALSE(bench_gimbal(*emu).status & kMoving);
  EXPECT_EQ(gimbal->read_state().fault, GimbalFault::none);
  move_and_wait(100, 100);
}

TEST_F(GimbalOnEmulator, ExceptionIsAClearErrorNamingRegisterAndCodeWithNoRetry) {
  start();
  gimbal->read_state();
  const auto retries0 = gimbal->counters().retries;

  // An injected exception 04 (server device failure) on a read.
  emu->inject("modbus_exception:code=4");
  uint64_t before = requests();
  std::string e = error_of([&] { gimbal->read_state(); });
  EXPECT_THAT(e, HasSubstr("read (function 04) of input registers 0..14 (pitch_position_mas..moves_completed)"));
  EXPECT_THAT(e, HasSubstr("Modbus exception 04"));
  EXPECT_EQ(requests(), before + 1);  // answered once, never sent again
  EXPECT_EQ(gimbal->counters().retries, retries0);

  // On the target write of a move: the move stops there (the command is never sent) and the
  // emulator's targets are untouched.
  const e2e::Targets t0 = bench_targets(*emu);
  emu->inject("modbus_exception:code=4");
  before = requests();
  e = error_of([&] { gimbal->move_to(500, 500); });
  EXPECT_THAT(e, HasSubstr("write (function 16) of holding registers 0..3 (pitch_target_mas..yaw_target_mas)"));
  EXPECT_THAT(e, HasSubstr("Modbus exception 04"));
  EXPECT_EQ(requests(), before + 1);
  EXPECT_EQ(bench_targets(*emu), t0);
  EXPECT_FALSE(bench_gimbal(*emu).status & kMoving);
  EXPECT_EQ(gimbal->counters().retries, retries0);

  // The gimbal is still usable on the same link.
  EXPECT_TRUE(gimbal->connected());
  move_and_wait(500, 500);
}

TEST_F(GimbalOnEmulator, HardLimitExceptionFromTheDeviceNamesTheRegisters) {
  EmulatorOptions o = e2e::emulator_options();
  emu = std::make_unique<Emulator>(o);
  emu->start();
  // Soft limits wider than the emulator's +-2 deg hard limits: the device itself refuses.
  GimbalOptions go = gimbal_options(emu->endpoints().gimbal());
  go.limits.pitch_min_arcsec = go.limits.yaw_min_arcsec = -9000;
  go.limits.pitch_max_arcsec = go.limits.yaw_max_arcsec = 9000;
  gimbal = std::make_unique<ModbusGimbal>(go);
  gimbal->connect();
  const uint64_t before = requests();
  const std::string e = error_of([&] { gimbal->move_to(8000, 0); });
  EXPECT_THAT(e, HasSubstr("holding registers 0..3 (pitch_target_mas..yaw_target_mas)"));
  EXPECT_THAT(e, HasSubstr("Modbus exception 03"));
  EXPECT_EQ(requests(), before + 1);
  EXPECT_EQ(bench_targets(*emu), (e2e::Targets{0, 0}));
  move_and_wait(7000, -7000);  // inside the hard limits: fine
}

TEST_F(GimbalOnEmulator, BusyExceptionIsRetriedOnTheSameLink) {
  start();
  gimbal->read_state();
  const auto conns0 = emu->stats().modbus_tcp.connections;
  emu->inject("modbus_exception:code=6,count=2");  // server busy, twice: inside the budget of 2 retries
  EXPECT_EQ(gimbal->read_state().fault, GimbalFault::none);
  EXPECT_EQ(gimbal->counters().retries, 2u);
  EXPECT_EQ(gimbal->counters().reconnects, 0u);
  EXPECT_EQ(emu->stats().modbus_tcp.connections, conns0);
}

TEST_F(GimbalOnEmulator, ReplyDelayedPastTheTimeoutIsRetriedOnAFreshLink) {
  // 0.3 s per request against a reply 2 s late: the first attempt times out for sure; a normal
  // loopback reply takes well under a millisecond.
  start(e2e::emulator_options(), 0.3);
  gimbal->read_state();
  emu->inject("modbus_delay:delay_s=2");
  expect_read_recovers_on_a_fresh_link();
  EXPECT_EQ(emu->stats().modbus_tcp.delayed, 1u);

  // A late answer to a move's target write: the write was executed, its retry writes the same
  // values again (idempotent) and the move completes.
  emu->inject("modbus_delay:delay_s=2");
  move_and_wait(-700, 350);
  EXPECT_EQ(bench_targets(*emu), (e2e::Targets{-700, 350}));
  EXPECT_EQ(emu->stats().modbus_tcp.delayed, 2u);
}

TEST_F(GimbalOnEmulator, DelaysBeyondTheRetryBudgetNameTheTimeoutAndTheLinkRecovers) {
  start(e2e::emulator_options(), 0.3);
  gimbal->read_state();
  const int attempts = gimbal->options().retries + 1;
  emu->inject("modbus_delay:delay_s=2,count=" + std::to_string(attempts));
  const std::string e = error_of([&] { gimbal->read_state(); });
  EXPECT_THAT(e, HasSubstr("input registers 0..14 (pitch_position_mas..moves_completed)"));
  EXPECT_THAT(e, HasSubstr("failed after " + std::to_string(attempts) + " attempts"));
  EXPECT_THAT(e, HasSubstr("timed out"));
  EXPECT_THAT(e, HasSubstr("errno " + std::to_string(ETIMEDOUT)));
  EXPECT_EQ(emu->stats().modbus_tcp.delayed, static_cast<uint64_t>(attempts));
  // The driver closed the link (a late answer must not be read as the next reply); the next
  // call reconnects and reads a consistent state.
  GimbalState s = gimbal->read_state();
  EXPECT_EQ(s.fault, GimbalFault::none);
  EXPECT_TRUE(s.has(kInPosition));
  move_and_wait(42, -42);
}

TEST_F(GimbalOnEmulator, FollowingErrorStopsTheGimbalAndClearFaultRecovers) {
  // A slow clock and a long move (1200 arcsec at 100 arcsec/s: 12 bench s, 2.4 wall s), so the
  // fault lands mid-move however the test thread is scheduled.
  start(e2e::emulator_options(5.0));
  gimbal->set_max_rate(100);
  gimbal->move_to(1200, -1200);
  ASSERT_TRUE(wait_until([&] { return gimbal->read_state().has(kMoving); }));
  emu->inject("following_error");

  const std::string e = error_of([&] { gimbal->wait_in_position(60.0); });
  EXPECT_THAT(e, HasSubstr("fault 1 (following_error) in input register 9"));
  EXPECT_THAT(e, HasSubstr("while waiting for in-position"));

  // Stopped where it was, fault latched.
  GimbalState s = gimbal->read_state();
  EXPECT_FALSE(s.has(kMoving));
  EXPECT_TRUE(s.has(kFault));
  EXPECT_EQ(s.fault, GimbalFault::following_error);
  EXPECT_EQ(s.pitch_rate_arcsec_s, 0);
  EXPECT_EQ(s.yaw_rate_arcsec_s, 0);
  EXPECT_LT(std::abs(s.pitch_arcsec), 1200 - 1);  // short of the target
  const GimbalReadout frozen = bench_gimbal(*emu);
  const double t_frozen = emu->bench_time_s();
  ASSERT_TRUE(wait_until([&] { return emu->bench_time_s() > t_frozen + 2.0; }));
  EXPECT_EQ(bench_gimbal(*emu).pitch_arcsec, frozen.pitch_arcsec);  // 2 bench s later: not a mas further
  EXPECT_EQ(bench_gimbal(*emu).yaw_arcsec, frozen.yaw_arcsec);

  // While faulted the device refuses a move (exception 03 on the command register): safe.
  const std::string refused = error_of([&] { gimbal->move_to(0, 0); });
  EXPECT_THAT(refused, HasSubstr("holding register 11 (command)"));
  EXPECT_THAT(refused, HasSubstr("Modbus exception 03"));
  EXPECT_FALSE(gimbal->read_state().has(kMoving));

  gimbal->clear_fault();
  EXPECT_EQ(gimbal->read_state().fault, GimbalFault::none);
  gimbal->set_max_rate(1800);
  move_and_wait(300, 300);
}

TEST_F(GimbalOnEmulator, SoftLimitsRefuseBeforeAnythingIsSent) {
  start();
  move_and_wait(100, 200);
  const e2e::Targets t0 = bench_targets(*emu);
  const uint64_t before = requests();

  std::string e = error_of([&] { gimbal->move_to(2700.5, 0); });
  EXPECT_THAT(e, HasSubstr("pitch target 2700.5 arcsec outside the soft limits [-2700, 2700] arcsec"));
  EXPECT_THAT(e, HasSubstr("nothing sent"));
  EXPECT_THROW(gimbal->move_to(0, -3000), LimitError);
  EXPECT_THROW(gimbal->move_to(std::nan(""), 0), LimitError);
  EXPECT_THROW(gimbal->start_rate(4000, 0), LimitError);
  EXPECT_THROW(gimbal->set_max_rate(0), LimitError);
  EXPECT_THROW(gimbal->set_max_rate(3601), LimitError);
  EXPECT_THROW(gimbal->set_watchdog(70), LimitError);

  // Not one request reached the emulator, and its target registers are unchanged.
  EXPECT_EQ(requests(), before);
  EXPECT_EQ(bench_targets(*emu), t0);
  const auto held = gimbal->read_holding_registers(gimbal_reg::kPitchTargetMas, 4);
  EXPECT_EQ(get_i32(held.data()), 100'000);
  EXPECT_EQ(get_i32(held.data() + 2), 200'000);
  EXPECT_FALSE(gimbal->read_state().has(kMoving));
}

TEST_F(GimbalOnEmulator, WatchdogStopsTheMoveWhenTheHostStopsPolling) {
  // Manual bench clock: polling and silence are bench-time facts, independent of the scheduler.
  EmulatorOptions o = e2e::emulator_options();
  o.manual_clock = true;
  start(o);
  gimbal->set_max_rate(100);
  gimbal->set_watchdog(2.0);
  EXPECT_EQ(gimbal->read_holding_registers(gimbal_reg::kWatchdogMs, 1)[0], 2000);
  gimbal->move_to(2000, 0);  // 20 bench s of motion

  // A host polling every 0.5 bench s keeps it alive for 5 bench s, well past the 2 s watchdog.
  for (int i = 0; i < 10; ++i) {
    emu->advance_by(0.5);
    GimbalState s = gimbal->read_state();
    ASSERT_TRUE(s.has(kMoving)) << "poll " << i;
    ASSERT_EQ(s.fault, GimbalFault::none) << "poll " << i;
  }
  // The host goes quiet for 3 bench s: the gimbal stops with fault 4.
  emu->advance_by(3.0);
  GimbalState s = gimbal->read_state();
  EXPECT_FALSE(s.has(kMoving));
  EXPECT_TRUE(s.has(kFault));
  EXPECT_EQ(s.fault, GimbalFault::watchdog);
  EXPECT_EQ(s.pitch_rate_arcsec_s, 0);
  EXPECT_GT(s.pitch_arcsec, 400);  // it had moved, and stopped short of the target
  EXPECT_LT(s.pitch_arcsec, 1000);
  const double stopped_at = bench_gimbal(*emu).pitch_arcsec;
  emu->advance_by(5.0);
  EXPECT_EQ(bench_gimbal(*emu).pitch_arcsec, stopped_at);
  EXPECT_THAT(error_of([&] { gimbal->wait_in_position(5.0); }), HasSubstr("fault 4 (watchdog)"));

  // Clear, turn the watchdog off, and the same move completes.
  gimbal->clear_fault();
  gimbal->set_watchdog(0);
  gimbal->move_to(2000, 0);
  GimbalState done = e2e::settle_manual(*emu, *gimbal, 1.0);
  EXPECT_EQ(done.fault, GimbalFault::none);
  EXPECT_NEAR(done.pitch_arcsec, 2000, 0.5);
}

TEST_F(GimbalOnEmulator, WatchdogFiresOnTheRealClockWhenNobodyPolls) {
  start(e2e::emulator_options(20.0));
  gimbal->set_max_rate(100);
  gimbal->set_watchdog(1.0);  // one bench second: 50 wall ms at speed 20
  gimbal->move_to(-2500, 0);
  // No request from the host: only the emulator's own clock runs.
  ASSERT_TRUE(wait_until([&] { return bench_gimbal(*emu).fault_code == 4; }, 30.0));
  GimbalState s = gimbal->read_state();
  EXPECT_EQ(s.fault, GimbalFault::watchdog);
  EXPECT_FALSE(s.has(kMoving));
  gimbal->clear_fault();
  gimbal->set_watchdog(0);
  move_and_wait(0, 0);
}

TEST(GimbalOverRtu, MovesAndRecoversFromAnUnansweredRequestOnTheEmulatorsPty) {
  const auto owned = started_emulator([](EmulatorOptions& o) { o.modbus_rtu = true; });
  Emulator& emu = *owned;
  ASSERT_FALSE(emu.endpoints().modbus_rtu_pty.empty());
  auto g = make_gimbal(gimbal_options(emu.endpoints().gimbal_rtu(), 0.5));
  auto& gimbal = dynamic_cast<ModbusGimbal&>(*g);
  gimbal.connect();
  GimbalState s0 = gimbal.read_state();
  EXPECT_EQ(s0.fault, GimbalFault::none);
  gimbal.move_to(-321.5, 654.25);
  GimbalState s = gimbal.wait_in_position(60.0);
  EXPECT_NEAR(s.pitch_arcsec, -321.5, 0.5);
  EXPECT_NEAR(s.yaw_arcsec, 654.25, 0.5);
  EXPECT_EQ(bench_targets(emu), (e2e::Targets{-321.5, 654.25}));
  EXPECT_GT(emu.stats().modbus_rtu.requests, 0u);
  EXPECT_EQ(emu.stats().modbus_tcp.requests, 0u);  // really over RTU

  // RTU has no connection to drop: the request goes unanswered, times out, and the retry works.
  emu.inject("modbus_drop");
  EXPECT_EQ(gimbal.read_state().fault, GimbalFault::none);
  EXPECT_EQ(emu.stats().modbus_rtu.dropped, 1u);
  EXPECT_GE(gimbal.counters().retries, 1u);

  // An exception answer over RTU: named, not retried.
  emu.inject("modbus_exception:code=4");
  const uint64_t before = emu.stats().modbus_rtu.requests;
  EXPECT_THAT(error_of([&] { gimbal.read_state(); }), HasSubstr("Modbus exception 04"));
  EXPECT_EQ(emu.stats().modbus_rtu.requests, before + 1);
  gimbal.move_to(0, 0);
  EXPECT_TRUE(gimbal.wait_in_position(60.0).has(kInPosition));
}

// RTU replies carry no transaction id: a reply that comes after the driver gave up on it must not
// be taken for the answer to a later request (every later read would then be one reply behind).
TEST(GimbalOverRtu, AReplyDelayedPastTheTimeoutIsNeverTakenForALaterOne) {
  const auto owned = started_emulator([](EmulatorOptions& o) { o.modbus_rtu = true; });
  Emulator& emu = *owned;
  GimbalOptions go = gimbal_options(emu.endpoints().gimbal_rtu(), 0.3);
  go.retries = 3;
  ModbusGimbal gimbal(go);
  gimbal.connect();
  gimbal.read_state();
  emu.inject("modbus_delay:delay_s=0.5");
  // A reply answers a request sent after the call began: its bench time is not older than that.
  // Half a bench second between calls makes a reply left over from the previous call stand out.
  auto fresh_read = [&] {
    const double t_prev_s = emu.bench_time_s();
    EXPECT_TRUE(wait_until([&] { return emu.bench_time_s() > t_prev_s + 0.5; }));
    const double t_before_s = emu.bench_time_s();
    GimbalState s = gimbal.read_state();
    EXPECT_GE(static_cast<double>(s.sample_time_us) * 1e-6, t_before_s - 1e-3);
    return s;
  };
  fresh_read();
  EXPECT_EQ(emu.stats().modbus_rtu.delayed, 1u);
  const uint64_t retries = gimbal.counters().retries;
  EXPECT_GE(retries, 1u);
  for (int i = 0; i < 3; ++i) fresh_read();
  // Writes and reads of other functions get their own replies, and a move is seen as it happens.
  gimbal.move_to(250, -250);
  EXPECT_NEAR(gimbal.wait_in_position(60.0).pitch_arcsec, 250, 0.5);
  EXPECT_EQ(get_i32(gimbal.read_holding_registers(gimbal_reg::kPitchTargetMas, 2).data()), 250'000);
  EXPECT_NEAR(fresh_read().yaw_arcsec, -250, 0.5);
  // Once the fault is over the line is clean: not one more retry.
  EXPECT_EQ(gimbal.counters().retries, retries);
}

}  // namespace
}  // namespace fpss
