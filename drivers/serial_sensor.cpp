// SerialSensor: reader thread -> frame parser -> sample queue / reply queue; commands as ASCII lines.
#include "drivers/serial_sensor.h"

#include <spdlog/spdlog.h>

#include <fmt/format.h>

#include <charconv>
#include <chrono>
#include <cmath>
#include <regex>

#include "drivers/endpoints.h"
#include "drivers/host_clock.h"

namespace fpss {
namespace {

using Clock = std::chrono::steady_clock;
auto secs(double s) { return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s)); }

constexpr double kReadSlice_s = 0.05;  // how often the reader thread looks at its stop flag

bool starts_with(const std::string& s, const char* p) { return s.rfind(p, 0) == 0; }
bool is_err(const std::string& r) { return r == "ERR" || starts_with(r, "ERR "); }
bool accept_ok(const std::string& r) { return r == "OK" || is_err(r); }
bool accept_id(const std::string& r) { return starts_with(r, "FPSS,") || is_err(r); }
bool accept_temp(const std::string& r) { return starts_with(r, "TEMP ") || is_err(r); }

}  // namespace

SerialSensor::SerialSensor(SensorOptions options) : options_(std::move(options)) {
  stream_ = make_byte_stream(options_.endpoint, options_.connect_timeout_s);  // parses only, no I/O
}

SerialSensor::SerialSensor(SensorOptions options, std::unique_ptr<ByteStream> stream)
    : options_(std::move(options)), stream_(std::move(stream)) {
  if (!stream_) throw LimitError("SerialSensor needs a byte stream");
}

SerialSensor::~SerialSensor() { disconnect(); }

void SerialSensor::connect() {
  disconnect();
  {
    std::lock_guard io(io_mu_);
    stream_->open();  // DeviceError naming the endpoint and errno
  }
  {
    std::lock_guard lk(mu_);
    running_ = true;
    link_up_ = true;
    failure_.clear();
    samples_.clear();
    replies_.clear();
    parser_ = frame::Parser();
    tracker_.reset();
    stats_ = SensorStats();
  }
  reader_ = std::thread([this] { reader_loop(); });
}

void SerialSensor::disconnect() {
  {
    std::lock_guard lk(mu_);
    running_ = false;
  }
  cv_.notify_all();
  if (reader_.joinable()) reader_.join();
  {
    std::lock_guard io(io_mu_);
    stream_->close();
  }
  std::lock_guard lk(mu_);
  link_up_ = false;
}

bool SerialSensor::connected() const {
  std::lock_guard lk(mu_);
  return running_ && link_up_ && failure_.empty();
}

void SerialSensor::reader_loop() {
  uint8_t buf[4096];
  for (;;) {
    {
      std::lock_guard lk(mu_);
      if (!running_) return;
    }
    std::size_t n = 0;
    try {
      n = stream_->read(buf, sizeof buf, kReadSlice_s);
    } catch (const DeviceError& e) {
      spdlog::warn("sensor {}: {}", options_.endpoint, e.what());
      {
        std::lock_guard io(io_mu_);
        stream_->close();
      }
      {
        std::lock_guard lk(mu_);
        link_up_ = false;
        parser_.reset();  // a frame cut by the drop is garbage
      }
      if (!reopen()) return;
      continue;
    }
    if (n == 0) continue;
    const double t = host_now_s();  // host receive time of every frame completed by this chunk
    std::lock_guard lk(mu_);
    parser_.feed(buf, n, [&](const frame::Frame& f) { on_frame(f, t); });
  }
}

bool SerialSensor::reopen() {
  double backoff = options_.reconnect_backoff_s;
  std::string last;
  for (int attempt = 1; attempt <= options_.reconnects; ++attempt) {
    {
      std::unique_lock lk(mu_);
      if (cv_.wait_for(lk, secs(backoff), [&] { return !running_; })) return false;
    }
    try {
      {
        std::lock_guard io(io_mu_);
        stream_->open();
      }
      std::lock_guard lk(mu_);
      link_up_ = true;
      ++stats_.reconnects;
      spdlog::info("sensor {}: link reopened (attempt {})", options_.endpoint, attempt);
      return true;
    } catch (const DeviceError& e) {
      last = e.what();
      spdlog::warn("sensor {}: reopen attempt {} of {} failed: {}", options_.endpoint, attempt, options_.reconnects,
                   last);
    }
    backoff *= 2;
  }
  fail(fmt::format("sensor {}: link lost and not reopened after {} attempts: {}", options_.endpoint,
                   options_.reconnects, last.empty() ? "no attempt allowed" : last));
  return false;
}

void SerialSensor::fail(std::string why) {
  {
    std::lock_guard lk(mu_);
    failure_ = std::move(why);
    link_up_ = false;
  }
  cv_.notify_all();
}

// Called with mu_ held.
void SerialSensor::on_frame(const frame::Frame& f, double host_time_s) {
  if (const auto* s = std::get_if<frame::SampleFrame>(&f)) {
    auto step = tracker_.observe(s->seq, s->sensor_time_us);
    SensorSample out;
    out.seq = s->seq;
    out.sensor_time_us = s->sensor_time_us;
    out.sensor_time_s = step.sensor_time_s;
    out.counts_alpha = s->counts_alpha;
    out.counts_beta = s->counts_beta;
    out.status = s->status;
    out.host_time_s = host_time_s;
    if (samples_.size() >= options_.max_queued_samples && !samples_.empty()) {
      samples_.pop_front();
      ++stats_.samples_dropped;
    }
    samples_.push_back(out);
  } else {
    replies_.push_back(std::get<frame::Reply>(f).text);
  }
  cv_.notify_all();
}

std::optional<SensorSample> SerialSensor::next_sample(double timeout_s) {
  std::unique_lock lk(mu_);
  if (!running_ && failure_.empty())
    throw DeviceError(fmt::format("sensor {}: next_sample before connect()", options_.endpoint));
  cv_.wait_for(lk, secs(std::max(0.0, timeout_s)), [&] { return !samples_.empty() || !failure_.empty(); });
  if (!samples_.empty()) {
    SensorSample s = samples_.front();
    samples_.pop_front();
    return s;
  }
  if (!failure_.empty()) throw DeviceError(failure_);
  return std::nullopt;
}

void SerialSensor::flush() {
  std::lock_guard lk(mu_);
  samples_.clear();
}

SensorStats SerialSensor::stats() const {
  std::lock_guard lk(mu_);
  SensorStats s = stats_;
  const auto& p = parser_.stats();
  s.frames = p.samples;
  s.replies = p.replies;
  s.crc_errors = p.crc_errors;
  s.garbage_bytes = p.garbage_bytes;
  s.seq_gaps = tracker_.seq_gaps();
  s.frames_lost = tracker_.frames_lost();
  return s;
}

std::string SerialSensor::exchange(const std::string& line, bool (*accept)(const std::string&)) {
  std::lock_guard cmd(cmd_mu_);
  const std::string wire = line + "\n";
  for (int attempt = 0;; ++attempt) {
    {
      std::lock_guard lk(mu_);
      if (!failure_.empty()) throw DeviceError(failure_);
      if (!running_) throw DeviceError(fmt::format("sensor {}: '{}' before connect()", options_.endpoint, line));
      replies_.clear();  // late answers to earlier commands are not ours
    }
    try {
      std::lock_guard io(io_mu_);
      if (!stream_->is_open())
        throw DeviceError(fmt::format("{}: link down, reconnecting", options_.endpoint));
      stream_->write(reinterpret_cast<const uint8_t*>(wire.data()), wire.size(), options_.command_timeout_s);
    } catch (const DeviceError& e) {
      // The reader thread sees the same dead link and reconnects; the retry below waits for it.
      spdlog::warn("sensor {}: sending '{}': {}", options_.endpoint, line, e.what());
    }
    std::unique_lock lk(mu_);
    const auto deadline = Clock::now() + secs(options_.command_timeout_s);
    for (;;) {
      while (!replies_.empty()) {
        std::string r = std::move(replies_.front());
        replies_.pop_front();
        if (!accept(r)) {
          spdlog::warn("sensor {}: ignoring reply '{}' while waiting for the answer to '{}'", options_.endpoint, r,
                       line);
          continue;
        }
        if (is_err(r))
          throw DeviceError(fmt::format("sensor {}: '{}' refused: {}", options_.endpoint, line,
                                        r.size() > 4 ? r.substr(4) : std::string("ERR (no reason given)")));
        return r;
      }
      if (!failure_.empty()) throw DeviceError(failure_);
      if (!cv_.wait_until(lk, deadline, [&] { return !replies_.empty() || !failure_.empty(); })) break;
    }
    if (attempt >= options_.command_retries)
      throw DeviceError(fmt::format("sensor {}: no reply to '{}' within {} s after {} attempts", options_.endpoint,
                                    line, options_.command_timeout_s, attempt + 1));
    spdlog::warn("sensor {}: no reply to '{}' within {} s; retry {} of {}", options_.endpoint, line,
                 options_.command_timeout_s, attempt + 1, options_.command_retries);
  }
}

std::string SerialSensor::command(const std::string& line) {
  if (line.empty() || line.find('\n') != std::string::npos || line.find('\r') != std::string::npos)
    throw LimitError(fmt::format("sensor command '{}' must be one non-empty line", line));
  if (starts_with(line, "ID?")) return exchange(line, accept_id);
  if (starts_with(line, "TEMP?")) return exchange(line, accept_temp);
  return exchange(line, accept_ok);
}

std::string SerialSensor::identify() { return exchange("ID?", accept_id); }

void SerialSensor::set_rate(int hz) {
  if (hz < 1 || hz > 200) throw LimitError(fmt::format("sensor rate {} Hz outside 1..200 Hz; nothing sent", hz));
  exchange(fmt::format("RATE {}", hz), accept_ok);
}

void SerialSensor::start() { exchange("START", accept_ok); }
void SerialSensor::stop() { exchange("STOP", accept_ok); }

double SerialSensor::temperature_c() {
  std::string r = exchange("TEMP?", accept_temp);
  std::string_view v = std::string_view(r).substr(5);
  // Plain decimal notation only (docs/icd.md): an optional minus, digits, an optional fraction.
  static const std::regex kDecimal(R"(-?[0-9]+(\.[0-9]+)?)");
  double c = 0;
  auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), c);
  if (!std::regex_match(v.begin(), v.end(), kDecimal) || ec != std::errc() || p != v.data() + v.size() ||
      !std::isfinite(c))
    throw DeviceError(fmt::format("sensor {}: reply to 'TEMP?' is '{}', expected 'TEMP <celsius>'",
                                  options_.endpoint, r));
  if (c < options_.temperature_min_c || c > options_.temperature_max_c)
    throw DeviceError(fmt::format("sensor {}: sensor temperature {} °C outside the plausible range {}..{} °C",
                                  options_.endpoint, v, options_.temperature_min_c, options_.temperature_max_c));
  return c;
}

}  // namespace fpss
