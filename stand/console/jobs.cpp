#include "stand/console/jobs.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <csignal>
#include <cstring>
#include <chrono>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include "base/clock.h"
#include "base/text_file.h"
#include "calib/coefficients.h"
#include "stand/console/run_files.h"

extern char** environ;

namespace fpss::console {

namespace fs = std::filesystem;

bool safe_name(const std::string& s, size_t max) {
  if (s.empty() || s.size() > max || s[0] == '.') return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == '-';
  });
}

std::string Job::investigation() const {
  if (kind != "investigate") return {};
  std::string stamp;  // 2026-11-27T12:00:00Z -> 20261127T120000Z, as investigate names its own
  for (char ch : created_utc.substr(0, 19)) {
    if (std::isalnum(static_cast<unsigned char>(ch))) stamp += ch;
  }
  return "investigation-" + stamp + "Z-job" + std::to_string(id);
}

nlohmann::json Job::to_json() const {
  const std::string inv = investigation();
  return {{"id", id},           {"kind", kind},         {"procedure", procedure}, {"model", model}, {"unit", unit},
          {"operator", operator_name}, {"state", state}, {"run_id", run_id.empty() ? nlohmann::json() : nlohmann::json(run_id)},
          {"investigation", inv.empty() ? nlohmann::json() : nlohmann::json(inv)},
          {"pid", pid},         {"exit_code", exit_code}, {"message", message},   {"created_utc", created_utc}};
}

// The jobs still queued are kept in RUNS_DIR/.console/queue.json (written whole at every change),
// so a restarted console keeps its queue; an entry that no longer validates is dropped.
void JobQueue::save() const {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& j : jobs_) {
    if (j.state == "queued") a.push_back(j.to_json());
  }
  try {
    std::error_code ec;
    fs::create_directories(o_.runs_dir / ".console", ec);
    write_text_atomic(o_.runs_dir / ".console" / "queue.json", nlohmann::json{{"next_id", next_id_}, {"queued", a}}.dump(1));
  } catch (const std::exception& e) {
    spdlog::warn("job queue: cannot save: {}", e.what());
  }
}

void JobQueue::load() {
  const fs::path p = o_.runs_dir / ".console" / "queue.json";
  if (!fs::exists(p)) return;
  try {
    const auto doc = nlohmann::json::parse(read_text_file(p, "console queue", 1024 * 1024));
    next_id_ = std::max<int64_t>(1, doc.value("next_id", int64_t{1}));
    for (const auto& x : doc.at("queued")) {
      Job j;
      j.kind = x.value("kind", "run");
      j.procedure = x.value("procedure", "");
      j.model = x.value("model", "");
      j.unit = x.value("unit", "");
      j.operator_name = x.value("operator", "");
      try {
        add(j);
      } catch (const std::invalid_argument& e) {
        spdlog::warn("{}: a queued job dropped: {}", p.string(), e.what());
      }
    }
  } catch (const std::exception& e) {
    spdlog::warn("{}: not read: {}", p.string(), e.what());
  }
}

JobQueue::JobQueue(const ConsoleOptions& o, CataloguePool& catalogue) : o_(o), catalogue_(catalogue) {
  load();
  thread_ = std::thread([this] { loop(); });
}

JobQueue::~JobQueue() {
  {
    std::lock_guard<std::mutex> g(m_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void JobQueue::check(const Job& j) const {
  if (j.kind != "run" && j.kind != "accept" && j.kind != "investigate") {
    throw std::invalid_argument("kind: \"run\", \"accept\" or \"investigate\"");
  }
  if (j.kind == "investigate") {
    const auto names = published_names();
    if (std::find(names.begin(), names.end(), j.model) == names.end()) {
      throw std::invalid_argument(fmt::format("model: \"{}\" is not a published set ({})", j.model,
                                              fmt::join(names, ", ")));
    }
  } else if (!j.model.empty()) {
    throw std::invalid_argument("model: only an investigate job takes one");
  }
  if (j.kind == "run" || !j.procedure.empty()) {
    if (!safe_name(j.procedure) || !fs::is_regular_file(o_.procedures_dir / j.procedure)) {
      throw std::invalid_argument(fmt::format("procedure: \"{}\" is not a file of {}", j.procedure, o_.procedures_dir.string()));
    }
  }
  if (!j.unit.empty() && !safe_name(j.unit)) throw std::invalid_argument("unit: 1-64 of A-Z a-z 0-9 . _ -");
  if (j.operator_name.size() > 100) throw std::invalid_argument("operator: at most 100 characters");
  if (!o_.emulate && j.unit.empty() && j.kind != "investigate") throw std::invalid_argument("unit: needed on a real stand");
}

Job JobQueue::add(Job j) {
  check(j);
  return add_all({std::move(j)}).front();
}

std::vector<Job> JobQueue::add_all(std::vector<Job> jobs) {
  if (jobs.size() > 1) {
    for (size_t i = 0; i < jobs.size(); ++i) {
      try {
        check(jobs[i]);
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(fmt::format("jobs[{}]: {}", i, e.what()));
      }
    }
  }
  std::lock_guard<std::mutex> g(m_);
  const auto queued = std::count_if(jobs_.begin(), jobs_.end(), [](const Job& x) { return x.state == "queued"; });
  if (static_cast<size_t>(queued) + jobs.size() > o_.max_queue) {
    throw std::invalid_argument(jobs.size() > 1 ? fmt::format("the queue holds {} of {}: no room for {} jobs", queued,
                                                              o_.max_queue, jobs.size())
                                                : std::string("the queue is full"));
  }
  for (Job& j : jobs) {
    j.id = next_id_++;
    j.state = "queued";
    j.created_utc = utc_now_iso();
    jobs_.push_back(j);
  }
  save();
  cv_.notify_all();
  return jobs;
}

bool JobQueue::remove(int64_t id) {
  std::lock_guard<std::mutex> g(m_);
  auto it = std::find_if(jobs_.begin(), jobs_.end(), [&](const Job& x) { return x.id == id && x.state == "queued"; });
  if (it == jobs_.end()) return false;
  jobs_.erase(it);
  save();
  return true;
}

bool JobQueue::move(int64_t id, size_t to) {
  std::lock_guard<std::mutex> g(m_);
  std::vector<Job> queued, other;
  for (auto& j : jobs_) (j.state == "queued" ? queued : other).push_back(j);
  auto it = std::find_if(queued.begin(), queued.end(), [&](const Job& x) { return x.id == id; });
  if (it == queued.end()) return false;
  Job j = *it;
  queued.erase(it);
  queued.insert(queued.begin() + static_cast<std::ptrdiff_t>(std::min(to, queued.size())), j);
  jobs_ = other;
  jobs_.insert(jobs_.end(), queued.begin(), queued.end());
  save();
  return true;
}

std::vector<Job> JobQueue::list() const {
  std::lock_guard<std::mutex> g(m_);
  return jobs_;
}

std::optional<Job> JobQueue::find(int64_t id) const {
  std::lock_guard<std::mutex> g(m_);
  for (const auto& j : jobs_) {
    if (j.id == id) return j;
  }
  return std::nullopt;
}

std::vector<std::string> JobQueue::argv_of(const Job& j) const {
  std::vector<std::string> a{o_.exe.string(), j.kind};
  if (j.kind == "run") a.push_back((o_.procedures_dir / j.procedure).string());
  if (j.kind == "accept" || j.kind == "investigate") {
    if (!j.procedure.empty()) a.insert(a.end(), {"--procedure", (o_.procedures_dir / j.procedure).string()});
  }
  if (j.kind == "accept") a.push_back("--operator-prompts");
  if (j.kind == "investigate") {
    a.insert(a.end(), {"--model", (published_dir() / (j.model + ".json")).string(), "--out",
                       (o_.runs_dir / j.investigation()).string()});
  }
  a.insert(a.end(), {"--runs-dir", o_.runs_dir.string(), "--quiet"});
  if (j.kind != "investigate") a.push_back("--no-progress");
  if (!o_.catalogue.empty()) a.insert(a.end(), {"--catalogue", o_.catalogue});
  if (j.kind == "run" && !j.operator_name.empty()) a.insert(a.end(), {"--operator", j.operator_name});
  if (o_.emulate) {
    a.push_back("--emulate");
    a.insert(a.end(), o_.emulator_args.begin(), o_.emulator_args.end());
    if (!j.unit.empty() && j.kind != "investigate") a.insert(a.end(), {j.kind == "run" ? "--unit-serial" : "--unit", j.unit});
  } else {
    a.insert(a.end(), {"--stand", o_.stand_file.string()});
    if (j.kind == "accept") a.insert(a.end(), {"--unit", j.unit});
  }
  return a;
}

// posix_spawn with argv (no shell), in a new session, output to RUNS/.console/job-N.log.
void JobQueue::start(Job& j) {
  const fs::path logs = o_.runs_dir / ".console";
  std::error_code ec;
  fs::create_directories(logs, ec);
  const std::string log = (logs / fmt::format("job-{}.log", j.id)).string();
  const std::vector<std::string> args = argv_of(j);
  std::vector<char*> argv;
  for (const auto& s : args) argv.push_back(const_cast<char*>(s.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawnattr_t at;
  posix_spawn_file_actions_init(&fa);
  posix_spawnattr_init(&at);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_NOFOLLOW, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  posix_spawnattr_setflags(&at, POSIX_SPAWN_SETSID | POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  sigset_t none, all;
  sigemptyset(&none);
  sigfillset(&all);
  posix_spawnattr_setsigmask(&at, &none);
  posix_spawnattr_setsigdefault(&at, &all);
  pid_t pid = 0;
  j.spawned_utc = utc_now_iso();  // before the child: its run starts in this second or later
  const int rc = posix_spawn(&pid, argv[0], &fa, &at, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&at);
  if (rc != 0) {
    j.state = "failed_to_start";
    j.message = fmt::format("cannot start {}: {}", args[0], std::strerror(rc));
    return;
  }
  j.pid = pid;
  j.state = "starting";
  spdlog::info("job {}: started {} (pid {})", j.id, fmt::join(args, " "), pid);
}

void JobQueue::tick() {
  std::lock_guard<std::mutex> g(m_);
  bool ours_active = false;
  for (auto& j : jobs_) {
    if (j.state != "starting" && j.state != "running") continue;
    if (j.run_id.empty()) {
      if (auto r = run_of_pid(catalogue_, j.pid, j.spawned_utc)) {
        j.run_id = r->run_id;
        j.state = "running";
      }
    }
    int status = 0;
    if (::waitpid(j.pid, &status, WNOHANG) == j.pid) {
      j.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      if (j.run_id.empty()) {
        if (auto r = run_of_pid(catalogue_, j.pid, j.spawned_utc)) j.run_id = r->run_id;
      }
      j.state = "finished";
      spdlog::info("job {}: exit {}", j.id, j.exit_code);
    } else {
      ours_active = true;
    }
  }
  if (ours_active) return;
  auto next = std::find_if(jobs_.begin(), jobs_.end(), [](const Job& x) { return x.state == "queued"; });
  if (next == jobs_.end()) return;
  // One stand: a run started by another console (or by hand) holds it too.
  if (!live_runs(catalogue_).empty()) return;
  start(*next);
  save();
}

void JobQueue::loop() {
  std::unique_lock<std::mutex> lk(m_);
  while (!stop_) {
    cv_.wait_for(lk, std::chrono::milliseconds(200));
    if (stop_) break;
    lk.unlock();
    try {
      tick();
    } catch (const std::exception& e) {
      spdlog::warn("job queue: {}", e.what());
    }
    lk.lock();
  }
}

}  // namespace fpss::console
