// An in-process Modbus server on libmodbus's own server API, for tests and benchmarks: below the wire.
// TCP on 127.0.0.1 with an ephemeral port, or RTU on the master side of a real pty.
#pragma once
#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

struct _modbus;
struct _modbus_mapping_t;

namespace fpss::test {

// A toy gimbal behind the ICD register map: enough behaviour to exercise the driver, no dynamics.
class ModbusTestServer {
 public:
  enum class Transport { tcp, rtu_pty };
  struct Request {
    int function = 0;
    int addr = 0;
    int count = 0;
    std::vector<uint16_t> values;  // written values (functions 06, 16)
  };
  // dribble: the normal reply, sent one byte at a time with dribble_s between bytes (TCP), as a
  // slow or misbehaving device would.
  enum class Action { reply, exception, drop, close, dribble };
  struct Decision {
    Action action = Action::reply;
    int exception_code = 0;
    double dribble_s = 0;
  };
  // Called for every request before the default behaviour; return nullopt-like {reply} to go on.
  using Hook = std::function<Decision(const Request&, std::size_t index)>;

  explicit ModbusTestServer(Transport t = Transport::tcp);
  ~ModbusTestServer();
  ModbusTestServer(const ModbusTestServer&) = delete;
  ModbusTestServer& operator=(const ModbusTestServer&) = delete;

  std::string endpoint() const;  // modbus-tcp:127.0.0.1:PORT or modbus-rtu:/dev/pts/N:115200
  int port() const { return port_; }

  void set_hook(Hook h);
  void set_recording(bool on);
  std::vector<Request> requests() const;
  std::size_t writes_seen() const;  // requests with function 06 or 16
  int connections() const { return connections_.load(); }

  void set_input(int addr, uint16_t v);
  void set_input_i32(int addr, int32_t v);
  void set_input_u64(int addr, uint64_t v);
  uint16_t holding(int addr) const;
  int32_t holding_i32(int addr) const;
  // After a move command the status shows "moving" for this many input-register reads.
  void set_move_reads(int n);
  // Fault raised by the next move command (GimbalFault code), 0 for none.
  void set_fault_on_move(uint16_t code);

 private:
  void run_tcp();
  void run_rtu();
  // Returns false when the connection should be closed.
  bool handle(const uint8_t* query, int length);
  void apply_command(uint16_t cmd);

  Transport transport_;
  _modbus* ctx_ = nullptr;
  _modbus_mapping_t* map_ = nullptr;
  int listen_fd_ = -1;
  int master_fd_ = -1, slave_fd_ = -1;
  std::string slave_path_;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<int> connections_{0};
  std::thread thread_;

  mutable std::mutex mu_;
  Hook hook_;
  bool recording_ = true;
  std::vector<Request> requests_;
  std::size_t writes_ = 0;
  std::size_t index_ = 0;
  int move_reads_ = 0, moving_left_ = 0;
  uint16_t fault_on_move_ = 0;
};

}  // namespace fpss::test
