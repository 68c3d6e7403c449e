// ModbusGimbal: the register map of docs/icd.md over libmodbus, with soft limits and the retry policy.
#include "drivers/modbus_gimbal.h"

#include <modbus.h>
#include <poll.h>
#include <spdlog/spdlog.h>

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <thread>

#include "drivers/endpoints.h"
#include "drivers/host_clock.h"

namespace fpss {

namespace gimbal_reg {
const char* input_name(int addr) {
  static const char* names[kInputCount] = {
      "pitch_position_mas", "pitch_position_mas", "yaw_position_mas", "yaw_position_mas",
      "pitch_rate_mas_s",   "pitch_rate_mas_s",   "yaw_rate_mas_s",   "yaw_rate_mas_s",
      "status",             "fault_code",         "sample_time_us",   "sample_time_us",
      "sample_time_us",     "sample_time_us",     "moves_completed"};
  return addr >= 0 && addr < kInputCount ? names[addr] : "unmapped";
}
const char* holding_name(int addr) {
  static const char* names[kMoveAtUs + kMoveAtCount] = {
      "pitch_target_mas",     "pitch_target_mas",     "yaw_target_mas",         "yaw_target_mas",
      "pitch_rate_cmd_mas_s", "pitch_rate_cmd_mas_s", "yaw_rate_cmd_mas_s",     "yaw_rate_cmd_mas_s",
      "max_rate_mas_s",       "max_rate_mas_s",       "in_position_window_mas", "command",
      "watchdog_ms",          "move_at_us",           "move_at_us",             "move_at_us",
      "move_at_us"};
  return addr >= 0 && addr < kMoveAtUs + kMoveAtCount ? names[addr] : "unmapped";
}
}  // namespace gimbal_reg

namespace {

using Clock = std::chrono::steady_clock;

constexpr double kMasPerArcsec = 1000.0;

const char* op_name(int op) {
  switch (op) {
    case 0: return "read (function 04)";
    case 1: return "read (function 03)";
    case 2: return "write (function 06)";
    default: return "write (function 16)";
  }
}

// "input registers 0..14 (pitch_position_mas..moves_completed)"
std::string where(int op, int addr, int count) {
  bool input = op == 0;
  auto name = [&](int a) { return input ? gimbal_reg::input_name(a) : gimbal_reg::holding_name(a); };
  const char* kind = input ? "input register" : "holding register";
  if (count <= 1) return fmt::format("{} {} ({})", kind, addr, name(addr));
  std::string first = name(addr), last = name(addr + count - 1);
  return fmt::format("{}s {}..{} ({})", kind, addr, addr + count - 1, first == last ? first : first + ".." + last);
}

bool is_exception(int e) { return e > MODBUS_ENOBASE && e <= EMBXGTAR; }

std::string exception_text(int e) {
  int code = e - MODBUS_ENOBASE;
  const char* meaning = "";
  if (code == MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS) meaning = ": the address is not mapped";
  if (code == MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE)
    meaning = ": value refused (target beyond the hard limits, or unknown command)";
  return fmt::format("Modbus exception {:02} ({}){}", code, modbus_strerror(e), meaning);
}

int32_t to_mas(double arcsec) {
  double mas = std::round(arcsec * kMasPerArcsec);
  // Callers check soft limits first; this only guards the int32 range of the wire format.
  if (!(mas >= -2147483648.0 && mas <= 2147483647.0))
    throw LimitError(fmt::format("{} arcsec does not fit an int32 of milliarcseconds", arcsec));
  return static_cast<int32_t>(mas);
}

// Bytes of the complete reply to a request (docs/icd.md): TCP adds the 7-byte MBAP header, RTU
// the address byte and the CRC.
int reply_bytes(int op, int count, bool rtu) {
  const int pdu = op <= 1 ? 2 + 2 * count : 5;  // reads: function, byte count, data; writes: echo
  return rtu ? 1 + pdu + 2 : 7 + pdu;
}

void check_range(const char* axis, double v, double lo, double hi, const char* unit) {
  if (!(v >= lo && v <= hi))  // NaN fails too
    throw LimitError(fmt::format("{} {} {} outside the soft limits [{}, {}] {}; nothing sent", axis, v, unit, lo,
                                 hi, unit));
}

}  // namespace

GimbalState decode_gimbal_state(const uint16_t* r) {
  using namespace gimbal_reg;
  GimbalState s;
  s.pitch_arcsec = get_i32(r + kPitchPositionMas) / kMasPerArcsec;
  s.yaw_arcsec = get_i32(r + kYawPositionMas) / kMasPerArcsec;
  s.pitch_rate_arcsec_s = get_i32(r + kPitchRateMasS) / kMasPerArcsec;
  s.yaw_rate_arcsec_s = get_i32(r + kYawRateMasS) / kMasPerArcsec;
  s.status = r[kStatus];
  s.fault = static_cast<GimbalFault>(r[kFaultCode]);
  s.sample_time_us = get_u64(r + kSampleTimeUs);
  s.moves_completed = r[kMovesCompleted];
  return s;
}

void ModbusGimbal::ContextDeleter::operator()(_modbus* ctx) const {
  modbus_close(ctx);
  modbus_free(ctx);
}

ModbusGimbal::ModbusGimbal(GimbalOptions options) : options_(std::move(options)) {
  Endpoint ep = parse_endpoint(options_.endpoint);  // fail early on a bad string, still no I/O
  rtu_ = ep.kind == Endpoint::Kind::modbus_rtu;
  if (ep.kind != Endpoint::Kind::modbus_tcp && ep.kind != Endpoint::Kind::modbus_rtu)
    throw EndpointError(fmt::format("bad gimbal endpoint '{}': expected modbus-tcp:HOST:PORT or "
                                    "modbus-rtu:DEVICE[:BAUD]",
                                    options_.endpoint));
  if (options_.unit_id < 0 || options_.unit_id > 247)
    throw LimitError(fmt::format("gimbal unit id {} outside 0..247", options_.unit_id));
  if (options_.retries < 0) throw LimitError(fmt::format("gimbal retries {} is negative", options_.retries));
  if (!(options_.response_timeout_s > 0))
    throw LimitError(fmt::format("gimbal response timeout {} s is not positive", options_.response_timeout_s));
}

ModbusGimbal::~ModbusGimbal() = default;

void ModbusGimbal::open_link() {
  Endpoint ep = parse_endpoint(options_.endpoint);
  modbus_t* raw;
  if (ep.kind == Endpoint::Kind::modbus_tcp) {
    raw = modbus_new_tcp_pi(ep.host.c_str(), std::to_string(ep.port).c_str());
  } else {
    raw = modbus_new_rtu(ep.path.c_str(), ep.baud, ep.parity, ep.data_bits, ep.stop_bits);
  }
  if (!raw)
    throw DeviceError(fmt::format("gimbal {}: cannot create the Modbus context: {} (errno {})", options_.endpoint,
                                  modbus_strerror(errno), errno));
  ctx_.reset(raw);
  modbus_set_slave(raw, options_.unit_id);
  modbus_set_error_recovery(raw, MODBUS_ERROR_RECOVERY_NONE);  // recovery is ours: counted and bounded
  auto sec = static_cast<uint32_t>(options_.response_timeout_s);
  auto usec = static_cast<uint32_t>(std::round((options_.response_timeout_s - sec) * 1e6));
  modbus_set_response_timeout(raw, sec, usec);
  if (modbus_connect(raw) != 0) {
    int e = errno;
    ctx_.reset();
    throw DeviceError(fmt::format("gimbal {}: cannot connect: {} (errno {})", options_.endpoint, modbus_strerror(e), e));
  }
  link_up_ = true;
}

void ModbusGimbal::close_link() {
  ctx_.reset();
  link_up_ = false;
}

// RTU replies carry no transaction id, and closing and reopening the port keeps what the
// device sent meanwhile: a reply that comes after the driver gave up on its request would be
// taken for the next request's, and every later read would be one reply behind. So before
// each request drop what is pending, and before a retry after a link failure also wait until
// the line has been quiet for one response timeout (bounded), dropping what arrives meanwhile.
void ModbusGimbal::discard_stale_rtu_input(bool until_quiet) {
  modbus_t* ctx = ctx_.get();
  modbus_flush(ctx);
  if (!until_quiet) return;
  const pollfd quiet{modbus_get_socket(ctx), POLLIN, 0};
  const int quiet_ms = std::max(1, static_cast<int>(std::lround(options_.response_timeout_s * 1000)));
  for (int round = 0; round < 16; ++round) {
    pollfd p = quiet;
    const int rc = ::poll(&p, 1, quiet_ms);
    if (rc == 0 || (rc < 0 && errno != EINTR)) return;
    modbus_flush(ctx);
  }
}

void ModbusGimbal::connect() {
  wanted_ = true;
  double backoff = options_.backoff_s;
  for (int attempt = 0;; ++attempt) {
    try {
      open_link();
      return;
    } catch (const DeviceError& e) {
      if (attempt >= options_.retries) {
        wanted_ = false;
        throw DeviceError(fmt::format("{} (after {} attempts)", e.what(), attempt + 1));
      }
      spdlog::warn("{}; retrying in {:.3f} s", e.what(), backoff);
      std::this_thread::sleep_for(std::chrono::duration<double>(backoff));
      backoff = std::min(backoff * 2, options_.max_backoff_s);
    }
  }
}

void ModbusGimbal::disconnect() {
  wanted_ = false;
  close_link();
}

bool ModbusGimbal::connected() const { return wanted_ && link_up_; }

int ModbusGimbal::transact(Op op, int addr, int count, uint16_t* regs) {
  const int o = static_cast<int>(op);
  if (!wanted_)
    throw DeviceError(fmt::format("gimbal {}: {} of {} before connect()", options_.endpoint, op_name(o),
                                  where(o, addr, count)));
  double backoff = options_.backoff_s;
  std::string last;
  bool link_failed = false;  // a late reply to an earlier attempt may still come (RTU)
  for (int attempt = 0;; ++attempt) {
    if (!link_up_) {
      try {
        open_link();
        ++counters_.reconnects;
        spdlog::info("gimbal {}: reconnected", options_.endpoint);
      } catch (const DeviceError& err) {
        last = err.what();
      }
    }
    if (link_up_) {
      if (rtu_) discard_stale_rtu_input(link_failed);
      modbus_t* ctx = ctx_.get();
      // libmodbus's response timeout covers only the first byte, and its byte timeout restarts
      // with every byte: a device sending its reply one byte every 0.1 s would hold a request for
      // seconds. So the byte timeout is the response timeout shared out over the reply's bytes
      // (over TCP each attempt then ends within twice the response timeout), and a reply complete
      // only after twice the response timeout counts as a timeout (docs/icd.md, section 4). Serial
      // links (USB adapters, ptys) deliver a reply in chunks with gaps of tens of milliseconds, so
      // over RTU the byte timeout is at least 0.1 s (or the response timeout when shorter).
      const double share_s = options_.response_timeout_s / reply_bytes(o, count, rtu_);
      const double byte_timeout_s =
          rtu_ ? std::max(share_s, std::min(0.1, options_.response_timeout_s)) : std::max(0.002, share_s);
      modbus_set_byte_timeout(ctx, 0, static_cast<uint32_t>(std::lround(byte_timeout_s * 1e6)));
      const auto started = Clock::now();
      int rc = -1;
      switch (op) {
        case Op::read_input: rc = modbus_read_input_registers(ctx, addr, count, regs); break;
        case Op::read_holding: rc = modbus_read_registers(ctx, addr, count, regs); break;
        case Op::write_single: rc = modbus_write_register(ctx, addr, regs[0]); break;
        case Op::write_multiple: rc = modbus_write_registers(ctx, addr, count, regs); break;
      }
      const double took_s = std::chrono::duration<double>(Clock::now() - started).count();
      if (rc >= 0 && took_s <= 2 * options_.response_timeout_s) {
        ++counters_.requests;
        return rc;
      }
      const int e = rc >= 0 ? ETIMEDOUT : errno;
      bool busy = e == EMBXSBUSY;
      if (is_exception(e) && !busy)
        throw DeviceError(fmt::format("gimbal {}: {} of {}: {}", options_.endpoint, op_name(o),
                                      where(o, addr, count), exception_text(e)));
      last = busy      ? exception_text(e)
             : rc >= 0 ? fmt::format("reply complete only after {:.3f} s, beyond twice the response timeout of {} s (errno {})",
                                     took_s, options_.response_timeout_s, e)
                       : fmt::format("{} (errno {})", modbus_strerror(e), e);
      // Timeout, dropped link, corrupt or mismatched reply: a late answer could still arrive and be
      // taken for the next one, so drop the link and start clean.
      if (!busy) {
        close_link();
        link_failed = true;
      }
    }
    if (attempt >= options_.retries)
      throw DeviceError(fmt::format("gimbal {}: {} of {} failed after {} attempts: {}", options_.endpoint,
                                    op_name(o), where(o, addr, count), attempt + 1, last));
    ++counters_.retries;
    spdlog::warn("gimbal {}: {} of {}: {}; retry {} of {} in {:.3f} s", options_.endpoint, op_name(o),
                 where(o, addr, count), last, attempt + 1, options_.retries, backoff);
    std::this_thread::sleep_for(std::chrono::duration<double>(backoff));
    backoff = std::min(backoff * 2, options_.max_backoff_s);
  }
}

GimbalState ModbusGimbal::read_state() {
  uint16_t r[gimbal_reg::kInputCount];
  transact(Op::read_input, 0, gimbal_reg::kInputCount, r);
  GimbalState s = decode_gimbal_state(r);
  s.host_time_s = host_now_s();
  return s;
}

std::vector<uint16_t> ModbusGimbal::read_registers(Op op, int addr, int count) {
  if (count < 1 || count > MODBUS_MAX_READ_REGISTERS)
    throw LimitError(fmt::format("register count {} outside 1..{}", count, MODBUS_MAX_READ_REGISTERS));
  std::vector<uint16_t> r(static_cast<std::size_t>(count));
  transact(op, addr, count, r.data());
  return r;
}

std::vector<uint16_t> ModbusGimbal::read_input_registers(int addr, int count) {
  return read_registers(Op::read_input, addr, count);
}

std::vector<uint16_t> ModbusGimbal::read_holding_registers(int addr, int count) {
  return read_registers(Op::read_holding, addr, count);
}

void ModbusGimbal::write_holding_registers(int addr, const std::vector<uint16_t>& values) {
  if (values.empty() || values.size() > MODBUS_MAX_WRITE_REGISTERS)
    throw LimitError(fmt::format("register count {} outside 1..{}", values.size(), MODBUS_MAX_WRITE_REGISTERS));
  std::vector<uint16_t> v = values;
  if (v.size() == 1)
    transact(Op::write_single, addr, 1, v.data());
  else
    transact(Op::write_multiple, addr, static_cast<int>(v.size()), v.data());
}

void ModbusGimbal::command(uint16_t cmd) {
  uint16_t v = cmd;
  transact(Op::write_single, gimbal_reg::kCommand, 1, &v);
}

void ModbusGimbal::set_max_rate(double arcsec_s) {
  const auto& L = options_.limits;
  if (!(arcsec_s > 0 && arcsec_s <= L.max_rate_arcsec_s))
    throw LimitError(fmt::format("max rate {} arcsec/s outside the soft limits (0, {}] arcsec/s; nothing sent",
                                 arcsec_s, L.max_rate_arcsec_s));
  double mas = std::round(arcsec_s * kMasPerArcsec);
  if (mas > 4294967295.0) throw LimitError(fmt::format("max rate {} arcsec/s does not fit a uint32 of mas/s", arcsec_s));
  auto u = static_cast<uint32_t>(mas);
  uint16_t r[2] = {static_cast<uint16_t>(u >> 16), static_cast<uint16_t>(u & 0xFFFF)};
  transact(Op::write_multiple, gimbal_reg::kMaxRateMasS, 2, r);
}

void ModbusGimbal::write_targets(double pitch_arcsec, double yaw_arcsec) {
  const auto& L = options_.limits;
  check_range("pitch target", pitch_arcsec, L.pitch_min_arcsec, L.pitch_max_arcsec, "arcsec");
  check_range("yaw target", yaw_arcsec, L.yaw_min_arcsec, L.yaw_max_arcsec, "arcsec");
  uint16_t r[4];
  put_i32(r, to_mas(pitch_arcsec));
  put_i32(r + 2, to_mas(yaw_arcsec));
  transact(Op::write_multiple, gimbal_reg::kPitchTargetMas, 4, r);
}

void ModbusGimbal::move_to(double pitch_arcsec, double yaw_arcsec) {
  write_targets(pitch_arcsec, yaw_arcsec);
  command(gimbal_reg::kCmdMove);
}

void ModbusGimbal::move_at(double pitch_arcsec, double yaw_arcsec, uint64_t start_us) {
  if (!timed_moves()) Gimbal::move_at(pitch_arcsec, yaw_arcsec, start_us);
  write_targets(pitch_arcsec, yaw_arcsec);
  uint16_t r[gimbal_reg::kMoveAtCount];
  for (int i = 0; i < gimbal_reg::kMoveAtCount; ++i) r[i] = static_cast<uint16_t>(start_us >> (48 - 16 * i));
  transact(Op::write_multiple, gimbal_reg::kMoveAtUs, gimbal_reg::kMoveAtCount, r);
  command(gimbal_reg::kCmdMoveAt);
}

GimbalState ModbusGimbal::wait_in_position(double timeout_s) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(std::max(0.0, timeout_s));
  for (;;) {
    GimbalState s = read_state();
    if (s.has(kFault) || s.fault != GimbalFault::none)
      throw DeviceError(fmt::format("gimbal {}: fault {} ({}) in input register 9 while waiting for in-position "
                                    "at pitch {} arcsec, yaw {} arcsec (status 0x{:04x})",
                                    options_.endpoint, static_cast<unsigned>(s.fault), to_string(s.fault),
                                    s.pitch_arcsec, s.yaw_arcsec, s.status));
    if (s.has(kInPosition) && !s.has(kMoving)) return s;
    if (Clock::now() >= deadline)
      throw DeviceError(fmt::format("gimbal {}: not in position within {} s: pitch {} arcsec, yaw {} arcsec, "
                                    "input register 8 (status) 0x{:04x}{}",
                                    options_.endpoint, timeout_s, s.pitch_arcsec, s.yaw_arcsec, s.status,
                                    s.has(kMoving) ? " (still moving)" : ""));
    std::this_thread::sleep_for(std::chrono::duration<double>(options_.poll_interval_s));
  }
}

void ModbusGimbal::start_rate(double pitch_arcsec_s, double yaw_arcsec_s) {
  const double m = options_.limits.max_rate_arcsec_s;
  check_range("pitch rate", pitch_arcsec_s, -m, m, "arcsec/s");
  check_range("yaw rate", yaw_arcsec_s, -m, m, "arcsec/s");
  uint16_t r[4];
  put_i32(r, to_mas(pitch_arcsec_s));
  put_i32(r + 2, to_mas(yaw_arcsec_s));
  transact(Op::write_multiple, gimbal_reg::kPitchRateCmdMasS, 4, r);
  command(gimbal_reg::kCmdStartRate);
}

void ModbusGimbal::stop() { command(gimbal_reg::kCmdStop); }
void ModbusGimbal::home() { command(gimbal_reg::kCmdHome); }
void ModbusGimbal::clear_fault() { command(gimbal_reg::kCmdClearFault); }

std::optional<GimbalCommand> ModbusGimbal::read_command() {
  using namespace gimbal_reg;
  const std::vector<uint16_t> r = read_holding_registers(0, kHoldingCount);
  GimbalCommand c;
  c.target_pitch_arcsec = get_i32(&r[kPitchTargetMas]) / kMasPerArcsec;
  c.target_yaw_arcsec = get_i32(&r[kYawTargetMas]) / kMasPerArcsec;
  c.max_rate_arcsec_s = get_u32(&r[kMaxRateMasS]) / kMasPerArcsec;
  c.command = r[kCommand];
  c.watchdog_s = r[kWatchdogMs] / 1000.0;
  return c;
}

void ModbusGimbal::set_watchdog(double seconds) {
  if (!(seconds >= 0 && seconds <= 65.535))
    throw LimitError(fmt::format("watchdog {} s outside 0..65.535 s (uint16 of ms); nothing sent", seconds));
  uint16_t v = static_cast<uint16_t>(std::lround(seconds * 1000.0));
  transact(Op::write_single, gimbal_reg::kWatchdogMs, 1, &v);
}

}  // namespace fpss
