// The gimbal over Modbus TCP or RTU (libmodbus), with the register map of docs/icd.md.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "drivers/gimbal.h"
#include "drivers/options.h"

struct _modbus;  // libmodbus's modbus_t, kept out of this header

namespace fpss {

// Register map (docs/icd.md). 32-bit values: two registers, high word first, two's complement.
namespace gimbal_reg {
// Input registers (function 04).
inline constexpr int kPitchPositionMas = 0, kYawPositionMas = 2, kPitchRateMasS = 4, kYawRateMasS = 6;
inline constexpr int kStatus = 8, kFaultCode = 9, kSampleTimeUs = 10, kMovesCompleted = 14;
inline constexpr int kInputCount = 15;
// Holding registers (functions 03, 06, 16).
inline constexpr int kPitchTargetMas = 0, kYawTargetMas = 2, kPitchRateCmdMasS = 4, kYawRateCmdMasS = 6;
inline constexpr int kMaxRateMasS = 8, kInPositionWindowMas = 10, kCommand = 11, kWatchdogMs = 12;
inline constexpr int kHoldingCount = 13;  // 0..12, every gimbal
// The scheduled move's start, uint64 us of the gimbal's clock (13..16), on a gimbal that has it.
inline constexpr int kMoveAtUs = 13, kMoveAtCount = 4;
// Values of the command register.
inline constexpr uint16_t kCmdMove = 1, kCmdStop = 2, kCmdHome = 3, kCmdClearFault = 4, kCmdStartRate = 5,
                          kCmdMoveAt = 6;
// Names for messages: "input register 9 (fault_code)".
const char* input_name(int addr);
const char* holding_name(int addr);
}  // namespace gimbal_reg

// Register encoding, exposed for tests and tools.
inline void put_i32(uint16_t* r, int32_t v) {
  auto u = static_cast<uint32_t>(v);
  r[0] = static_cast<uint16_t>(u >> 16);
  r[1] = static_cast<uint16_t>(u & 0xFFFF);
}
inline int32_t get_i32(const uint16_t* r) {
  return static_cast<int32_t>((static_cast<uint32_t>(r[0]) << 16) | r[1]);
}
inline uint32_t get_u32(const uint16_t* r) { return (static_cast<uint32_t>(r[0]) << 16) | r[1]; }
inline uint64_t get_u64(const uint16_t* r) {
  return (static_cast<uint64_t>(r[0]) << 48) | (static_cast<uint64_t>(r[1]) << 32) |
         (static_cast<uint64_t>(r[2]) << 16) | r[3];
}
// Decodes input registers 0..14 (exactly kInputCount values); host_time_s left for the caller.
GimbalState decode_gimbal_state(const uint16_t* regs);

struct ModbusCounters {
  uint64_t requests = 0;    // requests that got a good answer
  uint64_t retries = 0;     // repeated attempts after a timeout, dropped link or corrupt reply
  uint64_t reconnects = 0;  // links (re)opened after the first
};

// Not thread-safe: one owner drives it (the procedure engine).
class ModbusGimbal : public Gimbal {
 public:
  explicit ModbusGimbal(GimbalOptions options);  // parses the endpoint; touches no hardware
  ~ModbusGimbal() override;

  void connect() override;
  void disconnect() override;
  bool connected() const override;

  GimbalState read_state() override;  // input registers 0..14 in one request
  void set_max_rate(double arcsec_s) override;
  void move_to(double pitch_arcsec, double yaw_arcsec) override;
  bool timed_moves() const override { return options_.timed_moves; }  // the stand's word (GimbalOptions)
  void move_at(double pitch_arcsec, double yaw_arcsec, uint64_t start_us) override;
  GimbalState wait_in_position(double timeout_s) override;
  void start_rate(double pitch_arcsec_s, double yaw_arcsec_s) override;
  void stop() override;
  void home() override;
  void clear_fault() override;
  void set_watchdog(double seconds) override;
  std::optional<GimbalCommand> read_command() override;  // holding registers 0..12 in one request

  // Diagnostics: raw registers, with the same retry and error rules.
  std::vector<uint16_t> read_input_registers(int addr, int count);
  std::vector<uint16_t> read_holding_registers(int addr, int count);
  void write_holding_registers(int addr, const std::vector<uint16_t>& values);

  const GimbalOptions& options() const { return options_; }
  const ModbusCounters& counters() const { return counters_; }

 private:
  struct ContextDeleter {
    void operator()(_modbus* ctx) const;
  };
  enum class Op { read_input, read_holding, write_single, write_multiple };
  // One request with the retry policy; returns the libmodbus result or throws DeviceError.
  int transact(Op op, int addr, int count, uint16_t* regs);
  std::vector<uint16_t> read_registers(Op op, int addr, int count);  // count checked, then transact
  void open_link();   // new context + modbus_connect, one attempt; throws with errno
  void close_link();
  void discard_stale_rtu_input(bool until_quiet);
  void command(uint16_t cmd);
  void write_targets(double pitch_arcsec, double yaw_arcsec);  // soft limits, then holding 0..3

  GimbalOptions options_;
  std::unique_ptr<_modbus, ContextDeleter> ctx_;
  bool link_up_ = false;  // modbus_connect succeeded and no failure since
  bool wanted_ = false;   // connect() called and not disconnect(): failures may reconnect
  bool rtu_ = false;      // RTU: replies carry no transaction id (discard_stale_rtu_input)
  ModbusCounters counters_;
};

}  // namespace fpss
