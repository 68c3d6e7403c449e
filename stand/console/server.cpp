#include "stand/console/server.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <thread>

#include <fmt/format.h>
#include <httplib.h>
#include <spdlog/spdlog.h>

#include "base/unique_fd.h"
#include "stand/console/assets.h"
#include "stand/console/run_files.h"

namespace fpss::console {

namespace fs = std::filesystem;

Token load_or_create_token(const fs::path& runs_dir) {
  fs::create_directories(runs_dir);
  const fs::path p = runs_dir / "console.token";
  Token t;
  if (UniqueFd fd(::open(p.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600)); fd) {
    unsigned char raw[32];
    const UniqueFd r(::open("/dev/urandom", O_RDONLY | O_CLOEXEC));
    if (!r || ::read(r.get(), raw, sizeof raw) != static_cast<ssize_t>(sizeof raw)) {
      throw std::runtime_error("cannot read /dev/urandom for the console token");
    }
    for (unsigned char b : raw) t.value += fmt::format("{:02x}", b);
    const std::string line = t.value + "\n";
    const bool ok =
        ::write(fd.get(), line.data(), line.size()) == static_cast<ssize_t>(line.size()) && ::fsync(fd.get()) == 0;
    if (!ok) throw std::runtime_error(fmt::format("{}: cannot write the console token", p.string()));
    t.created = true;
    return t;
  }
  const UniqueFd fd(::open(p.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC));
  struct stat st {};
  if (!fd || ::fstat(fd.get(), &st) != 0 || !S_ISREG(st.st_mode)) {
    throw std::runtime_error(fmt::format("{}: not a regular file (the console token)", p.string()));
  }
  if ((st.st_mode & 077) != 0) {
    throw std::runtime_error(fmt::format("{}: readable by others (mode {:o}); chmod 600 it", p.string(), st.st_mode & 0777));
  }
  char buf[128] = {};
  const ssize_t n = ::read(fd.get(), buf, sizeof buf - 1);
  t.value.assign(buf, n > 0 ? static_cast<size_t>(n) : 0);
  while (!t.value.empty() && (t.value.back() == '\n' || t.value.back() == '\r')) t.value.pop_back();
  if (t.value.size() < 32) throw std::runtime_error(fmt::format("{}: too short to be a console token", p.string()));
  return t;
}

bool is_loopback(const std::string& host) {
  return host == "127.0.0.1" || host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

namespace {

bool same(const std::string& a, const std::string& b) {  // constant time for equal lengths
  if (a.size() != b.size()) return false;
  unsigned char d = 0;
  for (size_t i = 0; i < a.size(); ++i) d |= static_cast<unsigned char>(a[i] ^ b[i]);
  return d == 0;
}

std::string content_type(std::string_view path) {
  auto ends = [&](std::string_view e) { return path.size() >= e.size() && path.substr(path.size() - e.size()) == e; };
  if (ends(".html")) return "text/html; charset=utf-8";
  if (ends(".js")) return "text/javascript; charset=utf-8";
  if (ends(".css")) return "text/css; charset=utf-8";
  return "application/octet-stream";
}

std::string cookie_token(const httplib::Request& req) {
  const std::string c = req.get_header_value("Cookie");
  const std::string key = "fpss_console=";
  const size_t p = c.find(key);
  if (p == std::string::npos) return "";
  const size_t e = c.find(';', p);
  return c.substr(p + key.size(), e == std::string::npos ? std::string::npos : e - p - key.size());
}

}  // namespace

ConsoleServer::ConsoleServer(ConsoleOptions o) : svr_(std::make_unique<httplib::Server>()) {
  ctx_.opt = std::move(o);
  token_ = load_or_create_token(ctx_.opt.runs_dir);
  ctx_.token = token_.value;
}

ConsoleServer::~ConsoleServer() { stop(); }

// Writes need the bearer token always; reads need it (or the page's cookie) off loopback. On
// loopback the Host header must name loopback too, so a rebound DNS name cannot read the console.
bool ConsoleServer::authorised(const httplib::Request& req, httplib::Response& res) const {
  const std::string auth = req.get_header_value("Authorization");
  const bool bearer = auth.rfind("Bearer ", 0) == 0 && same(auth.substr(7), ctx_.token);
  const bool write = req.method != "GET" && req.method != "HEAD";
  const bool loopback = is_loopback(ctx_.opt.host);
  if (loopback) {
    std::string host = req.get_header_value("Host");
    host = host.substr(0, host.rfind(':') == std::string::npos ? host.size() : host.rfind(':'));
    if (!host.empty() && host != "[::1]" && !is_loopback(host)) {
      res.status = 403;
      res.set_content(R"({"error":"the console listens on loopback: use http://127.0.0.1"})", "application/json");
      return false;
    }
  }
  const bool asset = req.method == "GET" && (req.path == "/" || req.path.rfind("/api/", 0) != 0) &&
                     req.path.rfind("/runs/", 0) != 0;
  if (write ? bearer : (bearer || loopback || asset || same(cookie_token(req), ctx_.token))) return true;
  res.status = 401;
  res.set_header("WWW-Authenticate", "Bearer");
  res.set_content(R"j({"error":"this request needs the console's bearer token (RUNS_DIR/console.token)"})j",
                  "application/json");
  return false;
}

void ConsoleServer::bind() {
  httplib::Server& s = *svr_;
  s.set_payload_max_length(64 * 1024);  // JSON requests are small; headers are capped at 8 KiB by the library
  s.set_read_timeout(5, 0);
  s.set_write_timeout(5, 0);
  s.set_keep_alive_timeout(2);
  const size_t threads = ctx_.opt.max_live_clients + 8;
  s.new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    res.set_header("X-Content-Type-Options", "nosniff");
    res.set_header("Cache-Control", "no-store");
    return authorised(req, res) ? httplib::Server::HandlerResponse::Unhandled : httplib::Server::HandlerResponse::Handled;
  });
  s.Get("/", [](const httplib::Request&, httplib::Response& res) { res.set_redirect("/index.html"); });
  s.Get("/favicon.ico", [](const httplib::Request&, httplib::Response& res) { res.status = 204; });
  for (const Asset& a : assets()) {
    const std::string path(a.path), body(a.body), type = content_type(a.path);
    s.Get(path, [body, type](const httplib::Request&, httplib::Response& res) { res.set_content(body, type); });
  }
  // A connection for each request answered at once, at most 8: each takes one of a PostgreSQL server's slots.
  ctx_.catalogue = std::make_unique<CataloguePool>(ctx_.opt.runs_dir, ctx_.opt.catalogue, std::min<size_t>(threads, 8));
  ctx_.jobs = std::make_unique<JobQueue>(ctx_.opt, *ctx_.catalogue);
  add_api(s, ctx_);
  add_streams(s, ctx_);
  port_ = ctx_.opt.port;
  if (port_ == 0) {
    port_ = s.bind_to_any_port(ctx_.opt.host);
  } else if (!s.bind_to_port(ctx_.opt.host, port_)) {
    port_ = -1;
  }
  if (port_ <= 0) {
    // A token made by this start was never printed: the next start makes (and prints) a new one.
    std::error_code ec;
    if (token_.created) fs::remove(ctx_.opt.runs_dir / "console.token", ec);
    throw std::runtime_error(fmt::format("cannot listen on {}:{}", ctx_.opt.host, ctx_.opt.port));
  }
}

void ConsoleServer::serve() { svr_->listen_after_bind(); }

void ConsoleServer::stop() {
  ctx_.stopping = true;
  if (svr_) svr_->stop();
}

// ---- event streams ----

void add_streams(httplib::Server& s, Context& c) {
  // Server-Sent Events: each events.jsonl line is one message whose id is the byte offset after
  // it, so a page that reconnects (Last-Event-ID, or ?from=) continues where it stopped.
  s.Get(R"(/api/runs/([A-Za-z0-9._-]+)/stream)", [&c](const httplib::Request& req, httplib::Response& res) {
    const auto run = find_run(*c.catalogue, req.matches[1]);
    if (!run) {
      res.status = 404;
      res.set_content(R"({"error":"no such run"})", "application/json");
      return;
    }
    if (c.live_clients.fetch_add(1) >= c.opt.max_live_clients) {
      c.live_clients.fetch_sub(1);
      res.status = 503;
      res.set_content(R"({"error":"too many live clients"})", "application/json");
      return;
    }
    uint64_t from = 0;
    const std::string last = req.has_header("Last-Event-ID") ? req.get_header_value("Last-Event-ID")
                                                              : req.get_param_value("from");
    try {
      if (!last.empty()) from = std::stoull(last);
    } catch (const std::exception&) {
      from = 0;
    }
    const fs::path dir = run->dir;
    auto offset = std::make_shared<uint64_t>(from);
    const pid_t pid = run->pid;
    res.set_header("X-Accel-Buffering", "no");
    res.set_chunked_content_provider(
        "text/event-stream",
        [&c, dir, pid, offset](size_t, httplib::DataSink& sink) {
          for (int i = 0; i < 300 && !c.stopping; ++i) {  // 15 s at most per call, then a keep-alive
            if (sink.is_writable && !sink.is_writable()) return false;
            const EventChunk ch = read_events(dir, *offset);
            if (!ch.lines.empty()) {
              std::string out;
              for (size_t k = 0; k < ch.lines.size(); ++k) out += fmt::format("id: {}\ndata: {}\n\n", ch.ends[k], ch.lines[k]);
              *offset = ch.next;
              return sink.write(out.data(), out.size());
            }
            *offset = ch.next;
            // A run that has ended and has nothing more to send ends its stream.
            if (i % 40 == 39 && !run_alive(dir, pid)) {
              // What it wrote just before it ended is sent first.
              const EventChunk last = read_events(dir, *offset);
              std::string out;
              for (size_t k = 0; k < last.lines.size(); ++k) out += fmt::format("id: {}\ndata: {}\n\n", last.ends[k], last.lines[k]);
              *offset = last.next;
              if (!out.empty() && !sink.write(out.data(), out.size())) return false;
              sink.done();
              return true;
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(25));
          }
          if (c.stopping) return false;
          const std::string ka = ": keep-alive\n\n";
          return sink.write(ka.data(), ka.size());
        },
        [&c](bool) { c.live_clients.fetch_sub(1); });
  });
}

}  // namespace fpss::console
