// `fpss-stand serve`: the web console's HTTP server (cpp-httplib): pages from the binary, JSON API, live event streams, bearer token.
#pragma once
#include <atomic>
#include <memory>
#include <mutex>
#include <string>

#include "stand/console/jobs.h"

namespace httplib {
class Server;
class Request;
class Response;
}  // namespace httplib

namespace fpss::console {

// RUNS_DIR/console.token: made on first start (mode 0600, 32 random bytes as hex); `created` says
// whether this start made it (then serve prints it once). Throws std::runtime_error for a token
// file that others may read or that is not a regular file.
struct Token {
  std::string value;
  bool created = false;
};
Token load_or_create_token(const std::filesystem::path& runs_dir);

bool is_loopback(const std::string& host);

// What the API handlers share.
struct Context {
  ConsoleOptions opt;
  std::string token;
  // Held for the console's life; declared before the queue, which borrows it.
  std::unique_ptr<CataloguePool> catalogue;
  std::unique_ptr<JobQueue> jobs;
  std::atomic<size_t> live_clients{0};
  std::atomic<bool> stopping{false};
  std::mutex control_mutex;  // one writer of control.json at a time
};

// Registers the JSON API (api.cpp) and the run-file downloads.
void add_api(httplib::Server& s, Context& c);
// Registers the event streams (Server-Sent Events) of runs.
void add_streams(httplib::Server& s, Context& c);

class ConsoleServer {
 public:
  explicit ConsoleServer(ConsoleOptions o);
  ~ConsoleServer();
  // Binds; throws std::runtime_error naming the address when it cannot.
  void bind();
  int port() const { return port_; }
  const Token& token() const { return token_; }
  // Serves until stop() (another thread or a signal thread).
  void serve();
  void stop();

 private:
  bool authorised(const httplib::Request& req, httplib::Response& res) const;
  Context ctx_;
  Token token_;
  std::unique_ptr<httplib::Server> svr_;
  int port_ = 0;
};

}  // namespace fpss::console
