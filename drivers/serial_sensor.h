// The FPSS electronics over a byte stream: reader thread, frame parser, command/reply exchange.
#pragma once
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "drivers/byte_stream.h"
#include "drivers/fpss_frame.h"
#include "drivers/options.h"
#include "drivers/sensor.h"

namespace fpss {

// Thread-safe: a reader thread owns the stream's input side; commands and next_sample may come
// from any thread (commands are serialised).
class SerialSensor : public Sensor {
 public:
  explicit SerialSensor(SensorOptions options);  // parses the endpoint; touches no hardware
  // With a stream made elsewhere (its endpoint string is used in messages only).
  SerialSensor(SensorOptions options, std::unique_ptr<ByteStream> stream);
  ~SerialSensor() override;

  void connect() override;
  void disconnect() override;
  bool connected() const override;

  std::string identify() override;
  void set_rate(int hz) override;
  void start() override;
  void stop() override;
  double temperature_c() override;
  std::optional<SensorSample> next_sample(double timeout_s) override;
  void flush() override;
  SensorStats stats() const override;

  // One command line (no '\n'); returns the reply text. ERR -> DeviceError with the reason.
  std::string command(const std::string& line);

  const SensorOptions& options() const { return options_; }

 private:
  void reader_loop();
  bool reopen();  // reader thread: reconnect within limits after the link dropped
  void on_frame(const frame::Frame& f, double host_time_s);
  void fail(std::string why);  // reader thread: give up; waiters get DeviceError(why)
  std::string exchange(const std::string& line, bool (*accept)(const std::string&));

  SensorOptions options_;
  std::unique_ptr<ByteStream> stream_;
  std::thread reader_;

  mutable std::mutex mu_;  // guards everything below
  std::condition_variable cv_;
  bool running_ = false;   // reader thread should keep going
  bool link_up_ = false;
  std::string failure_;    // non-empty: the link is lost for good
  std::deque<SensorSample> samples_;
  std::deque<std::string> replies_;
  frame::Parser parser_;   // reader thread only, stats read under mu_
  frame::StreamTracker tracker_;
  SensorStats stats_;

  std::mutex cmd_mu_;  // one command exchange at a time
  // Guards stream_ open/close/write. The reader thread reads without it (one reader, one writer
  // may share a stream) and is the only one to close or reopen it while running.
  std::mutex io_mu_;
};

}  // namespace fpss
