// The console's job queue: pending runs and acceptances, started one at a time as detached `fpss-stand run`/`accept` child processes.
#pragma once
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "stand/console/catalogue_pool.h"

namespace fpss::console {

// What serve was started with (docs/console.md).
struct ConsoleOptions {
  std::filesystem::path runs_dir = "runs";
  std::string catalogue;  // URL (serve --catalogue); "" for RUNS_DIR/stand.db, as run and accept default
  std::string host = "127.0.0.1";
  int port = 8080;
  std::filesystem::path stand_file;               // a real bench, or
  bool emulate = false;                           // the emulated bench (each run starts its own)
  std::vector<std::string> emulator_args;         // passed on to run/accept (--speed K, --seed S, ...)
  std::filesystem::path procedures_dir;           // what the start page offers
  std::filesystem::path exe;                      // this binary
  size_t max_live_clients = 8;                    // event streams at once
  size_t max_queue = 100;
};

struct Job {
  int64_t id = 0;
  std::string kind = "run";   // "run", "accept" or "investigate"
  std::string procedure;      // file name inside the procedures folder ("" for accept and investigate: the default)
  std::string model;          // investigate: the sim model, a published set's name (calib/data/published)
  std::string unit, operator_name;
  std::string state = "queued";  // queued, starting, running, finished, failed_to_start, removed
  std::string run_id;            // once the child has made its run folder
  int pid = 0;
  int exit_code = -1;
  std::string message;           // why it failed to start
  std::string created_utc;
  std::string spawned_utc;       // when its child was started (its run starts then or later)
  // An investigate job's folder in the runs folder: investigation-<created, UTC>-job<id> ("" otherwise).
  std::string investigation() const;
  nlohmann::json to_json() const;
};

// Children run in their own session (setsid): killing serve, or its terminal closing, never
// stops them. The queue starts the next job only when no run of the runs folder is live.
class JobQueue {
 public:
  // The queue borrows the console's catalogue pool, which outlives it.
  JobQueue(const ConsoleOptions& o, CataloguePool& catalogue);
  ~JobQueue();
  JobQueue(const JobQueue&) = delete;
  JobQueue& operator=(const JobQueue&) = delete;

  // Throws std::invalid_argument (HTTP 400) for an unknown procedure, a bad serial or a full queue.
  Job add(Job j);
  // Every job or none (a plan's, e.g. `msa plan`): the first bad one is named "jobs[i]: ...", and
  // the queue must hold them all.
  std::vector<Job> add_all(std::vector<Job> jobs);
  bool remove(int64_t id);          // only a queued job
  bool move(int64_t id, size_t to);  // reorder among queued jobs
  std::vector<Job> list() const;
  std::optional<Job> find(int64_t id) const;
  // The argv a job runs with (for the docs and tests).
  std::vector<std::string> argv_of(const Job& j) const;

 private:
  void loop();
  void tick();
  void save() const;  // under m_
  void load();
  void start(Job& j);
  void check(const Job& j) const;  // std::invalid_argument naming the field
  ConsoleOptions o_;
  CataloguePool& catalogue_;
  mutable std::mutex m_;
  std::vector<Job> jobs_;
  int64_t next_id_ = 1;
  std::atomic<bool> stop_{false};
  std::condition_variable cv_;
  std::thread thread_;
};

// A name is safe when it is 1-64 of [A-Za-z0-9._-] and does not start with a dot.
bool safe_name(const std::string& s, size_t max = 64);

}  // namespace fpss::console
