// ModbusTestServer: poll() over the listening socket and clients, libmodbus receive/reply per request.
#include "modbus_test_server.h"

#include <arpa/inet.h>
#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <pty.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <chrono>
#include <stdexcept>
#include <thread>

namespace fpss::test {
namespace {
constexpr int kInputs = 15, kHoldings = 13;
constexpr int32_t kHardLimitMas = 7'200'000;  // +-2 deg
}  // namespace

ModbusTestServer::ModbusTestServer(Transport t) : transport_(t) {
  map_ = modbus_mapping_new(0, 0, kHoldings, kInputs);
  if (!map_) throw std::runtime_error("modbus_mapping_new failed");
  map_->tab_input_registers[8] = 0x0001 | 0x0004;  // homed, in position
  if (t == Transport::tcp) {
    ctx_ = modbus_new_tcp("127.0.0.1", 0);
    listen_fd_ = modbus_tcp_listen(ctx_, 8);
    if (listen_fd_ < 0) throw std::runtime_error(std::string("modbus_tcp_listen: ") + modbus_strerror(errno));
    sockaddr_in a{};
    socklen_t len = sizeof a;
    getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] { run_tcp(); });
  } else {
    char name[256];
    if (openpty(&master_fd_, &slave_fd_, name, nullptr, nullptr) != 0) throw std::runtime_error("openpty failed");
    slave_path_ = name;
    termios tio{};
    tcgetattr(master_fd_, &tio);
    cfmakeraw(&tio);
    tcsetattr(master_fd_, TCSANOW, &tio);
    // The RTU backend reads and writes ctx->s: point it at the pty master.
    ctx_ = modbus_new_rtu(slave_path_.c_str(), 115200, 'N', 8, 1);
    modbus_set_slave(ctx_, 1);
    modbus_set_socket(ctx_, master_fd_);
    thread_ = std::thread([this] { run_rtu(); });
  }
}

ModbusTestServer::~ModbusTestServer() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  if (listen_fd_ >= 0) close(listen_fd_);
  if (ctx_) {
    if (transport_ == Transport::rtu_pty) modbus_set_socket(ctx_, -1);  // we close the fds ourselves
    modbus_free(ctx_);
  }
  if (master_fd_ >= 0) close(master_fd_);
  if (slave_fd_ >= 0) close(slave_fd_);
  modbus_mapping_free(map_);
}

std::string ModbusTestServer::endpoint() const {
  if (transport_ == Transport::tcp) return "modbus-tcp:127.0.0.1:" + std::to_string(port_);
  return "modbus-rtu:" + slave_path_ + ":115200";
}

void ModbusTestServer::run_tcp() {
  std::vector<pollfd> fds{{listen_fd_, POLLIN, 0}};
  uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
  while (!stop_) {
    if (poll(fds.data(), fds.size(), 20) <= 0) continue;
    for (std::size_t i = fds.size(); i-- > 0;) {
      if (!fds[i].revents) continue;
      if (fds[i].fd == listen_fd_) {
        int s = listen_fd_;
        int c = modbus_tcp_accept(ctx_, &s);
        if (c >= 0) {
          fds.push_back({c, POLLIN, 0});
          ++connections_;
        }
        continue;
      }
      modbus_set_socket(ctx_, fds[i].fd);
      int rc = modbus_receive(ctx_, query);
      bool keep = rc != -1 && (rc == 0 || handle(query, rc));
      if (!keep) {
        close(fds[i].fd);
        fds.erase(fds.begin() + static_cast<std::ptrdiff_t>(i));
      }
    }
  }
  for (std::size_t i = 1; i < fds.size(); ++i) close(fds[i].fd);
}

void ModbusTestServer::run_rtu() {
  uint8_t query[MODBUS_RTU_MAX_ADU_LENGTH];
  modbus_set_indication_timeout(ctx_, 0, 50000);
  while (!stop_) {
    pollfd p{master_fd_, POLLIN, 0};
    if (poll(&p, 1, 20) <= 0) continue;
    if (!(p.revents & POLLIN)) {  // slave closed by the driver: nothing to read until it reopens
      usleep(5000);
      continue;
    }
    int rc = modbus_receive(ctx_, query);
    if (rc > 0) handle(query, rc);
  }
}

bool ModbusTestServer::handle(const uint8_t* q, int length) {
  const int h = modbus_get_header_length(ctx_);
  Request r;
  r.function = q[h];
  r.addr = (q[h + 1] << 8) | q[h + 2];
  if (r.function == MODBUS_FC_WRITE_SINGLE_REGISTER) {
    r.count = 1;
    r.values.push_back(static_cast<uint16_t>((q[h + 3] << 8) | q[h + 4]));
  } else {
    r.count = (q[h + 3] << 8) | q[h + 4];
    if (r.function == MODBUS_FC_WRITE_MULTIPLE_REGISTERS)
      for (int k = 0; k < r.count && h + 6 + 2 * k + 1 < length; ++k)
        r.values.push_back(static_cast<uint16_t>((q[h + 6 + 2 * k] << 8) | q[h + 7 + 2 * k]));
  }
  std::unique_lock lk(mu_);
  const bool write = r.function == MODBUS_FC_WRITE_SINGLE_REGISTER || r.function == MODBUS_FC_WRITE_MULTIPLE_REGISTERS;
  if (write) ++writes_;
  if (recording_) requests_.push_back(r);
  Decision d;
  if (hook_) d = hook_(r, index_);
  ++index_;
  if (d.action == Action::drop) return true;
  if (d.action == Action::dribble && transport_ == Transport::tcp) {
    // The reply libmodbus would send, captured on a socket pair, then trickled out byte by byte.
    int sp[2];
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sp) != 0) return false;
    const int client = modbus_get_socket(ctx_);
    modbus_set_socket(ctx_, sp[0]);
    modbus_reply(ctx_, q, length, map_);
    modbus_set_socket(ctx_, client);
    uint8_t reply[MODBUS_TCP_MAX_ADU_LENGTH];
    const ssize_t n = recv(sp[1], reply, sizeof reply, MSG_DONTWAIT);
    close(sp[0]);
    close(sp[1]);
    lk.unlock();
    for (ssize_t k = 0; k < n && !stop_; ++k) {
      if (send(client, reply + k, 1, MSG_NOSIGNAL) != 1) return false;  // the client gave up
      std::this_thread::sleep_for(std::chrono::duration<double>(d.dribble_s));
    }
    return true;
  }
  if (d.action == Action::close) return false;
  if (d.action == Action::exception) {
    modbus_reply_exception(ctx_, q, d.exception_code);
    return true;
  }
  // The toy device refuses what the ICD says it refuses: targets beyond the hard limits, unknown commands.
  if (write && r.addr <= 11 && r.addr + r.count > 11) {
    uint16_t cmd = r.values[static_cast<std::size_t>(11 - r.addr)];
    if (cmd < 1 || cmd > 5) {
      modbus_reply_exception(ctx_, q, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
      return true;
    }
  }
  if (write && r.addr < 4) {
    for (int k = 0; k + 1 < r.count; ++k) {
      int a = r.addr + k;
      if (a == 0 || a == 2) {
        auto v = static_cast<int32_t>((static_cast<uint32_t>(r.values[k]) << 16) | r.values[k + 1]);
        if (v > kHardLimitMas || v < -kHardLimitMas) {
          modbus_reply_exception(ctx_, q, MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
          return true;
        }
      }
    }
  }
  if (r.function == MODBUS_FC_READ_INPUT_REGISTERS) {
    uint16_t& status = map_->tab_input_registers[8];
    if (moving_left_ > 0) {
      --moving_left_;
      status = static_cast<uint16_t>((status | 0x0002) & ~0x0004);
    } else if (status & 0x0002) {
      map_->tab_input_registers[0] = map_->tab_registers[0];  // arrive at the target
      map_->tab_input_registers[1] = map_->tab_registers[1];
      map_->tab_input_registers[2] = map_->tab_registers[2];
      map_->tab_input_registers[3] = map_->tab_registers[3];
      status = static_cast<uint16_t>((status & ~0x0002) | 0x0004);
      ++map_->tab_input_registers[14];
    }
  }
  modbus_reply(ctx_, q, length, map_);
  if (write && r.addr <= 11 && r.addr + r.count > 11) apply_command(map_->tab_registers[11]);
  return true;
}

void ModbusTestServer::apply_command(uint16_t cmd) {
  uint16_t* in = map_->tab_input_registers;
  if (cmd == 1) {
    if (fault_on_move_) {
      in[8] = static_cast<uint16_t>((in[8] | 0x0008) & ~0x0006);
      in[9] = fault_on_move_;
      return;
    }
    moving_left_ = move_reads_;
    in[8] = static_cast<uint16_t>((in[8] | 0x0002) & ~0x0004);
  } else if (cmd == 2) {
    moving_left_ = 0;
    in[8] = static_cast<uint16_t>(in[8] & ~0x0042);
  } else if (cmd == 4) {
    in[8] = static_cast<uint16_t>(in[8] & ~0x0008);
    in[9] = 0;
  } else if (cmd == 5) {
    for (int k = 4; k < 8; ++k) in[k] = map_->tab_registers[k];
    in[8] = static_cast<uint16_t>(in[8] | 0x0042);
  }
}

void ModbusTestServer::set_hook(Hook h) {
  std::lock_guard lk(mu_);
  hook_ = std::move(h);
}
void ModbusTestServer::set_recording(bool on) {
  std::lock_guard lk(mu_);
  recording_ = on;
}
std::vector<ModbusTestServer::Request> ModbusTestServer::requests() const {
  std::lock_guard lk(mu_);
  return requests_;
}
std::size_t ModbusTestServer::writes_seen() const {
  std::lock_guard lk(mu_);
  return writes_;
}
void ModbusTestServer::set_input(int addr, uint16_t v) {
  std::lock_guard lk(mu_);
  map_->tab_input_registers[addr] = v;
}
void ModbusTestServer::set_input_i32(int addr, int32_t v) {
  std::lock_guard lk(mu_);
  auto u = static_cast<uint32_t>(v);
  map_->tab_input_registers[addr] = static_cast<uint16_t>(u >> 16);
  map_->tab_input_registers[addr + 1] = static_cast<uint16_t>(u);
}
void ModbusTestServer::set_input_u64(int addr, uint64_t v) {
  std::lock_guard lk(mu_);
  for (int k = 0; k < 4; ++k) map_->tab_input_registers[addr + k] = static_cast<uint16_t>(v >> (48 - 16 * k));
}
uint16_t ModbusTestServer::holding(int addr) const {
  std::lock_guard lk(mu_);
  return map_->tab_registers[addr];
}
int32_t ModbusTestServer::holding_i32(int addr) const {
  std::lock_guard lk(mu_);
  return static_cast<int32_t>((static_cast<uint32_t>(map_->tab_registers[addr]) << 16) | map_->tab_registers[addr + 1]);
}
void ModbusTestServer::set_move_reads(int n) {
  std::lock_guard lk(mu_);
  move_reads_ = n;
}
void ModbusTestServer::set_fault_on_move(uint16_t code) {
  std::lock_guard lk(mu_);
  fault_on_move_ = code;
}

}  // namespace fpss::test
