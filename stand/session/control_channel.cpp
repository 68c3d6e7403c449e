#include "stand/session/control_channel.h"

#include <sys/stat.h>

#include <chrono>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "base/clock.h"
#include "base/json_file.h"
#include "base/text_file.h"
#include "procedures/recorder.h"

namespace fpss {

namespace fs = std::filesystem;

std::optional<ControlRequest> read_control(const fs::path& run_dir) {
  const fs::path p = run_dir / kControlFile;
  struct stat st {};
  if (::lstat(p.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || static_cast<std::uintmax_t>(st.st_size) > kMaxControlFileBytes) {
    return std::nullopt;
  }
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  nlohmann::json j;
  try {
    j = parse_json_text(ss.str(), p.string(), 4);  // depth, duplicate keys
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (!j.is_object()) return std::nullopt;
  ControlRequest c;
  if (j.contains("pause") && j["pause"].is_boolean()) c.pause = j["pause"].get<bool>();
  if (j.contains("abort") && j["abort"].is_boolean()) c.abort = j["abort"].get<bool>();
  if (j.contains("answers") && j["answers"].is_object()) {
    for (const auto& [k, v] : j["answers"].items()) {
      if (v.is_string()) c.answers[k] = v.get<std::string>();
    }
  }
  return c;
}

void write_control(const fs::path& run_dir, const ControlRequest& c) {
  nlohmann::json j{{"pause", c.pause}, {"abort", c.abort}, {"answers", c.answers}};
  write_text_atomic(run_dir / kControlFile, j.dump(1) + "\n");
}

ControlPoller::ControlPoller(fs::path run_dir, RunControl& control)
    : dir_(std::move(run_dir)), control_(control) {
  // A request left by an earlier session (a resumed run) is history, not a new request: the
  // session starts from a clean channel.
  write_control(dir_, last_);
  thread_ = std::thread([this] { loop(); });
}

ControlPoller::~ControlPoller() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void ControlPoller::loop() {
  while (!stop_) {
    if (auto c = read_control(dir_)) {
      std::lock_guard<std::mutex> g(m_);
      if (c->pause != last_.pause) control_.pause.store(c->pause);
      if (c->abort && !last_.abort) control_.abort.store(true);
      last_ = *c;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

std::optional<std::string> ControlPoller::wait_answer(const std::string& id) {
  while (!control_.abort.load()) {
    {
      std::lock_guard<std::mutex> g(m_);
      auto it = last_.answers.find(id);
      if (it != last_.answers.end()) return it->second;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return std::nullopt;
}

OperatorAnswers ask_operator(const std::vector<OperatorPrompt>& prompts, const std::string& unit_serial,
                             ControlPoller& poller, RunControl& control, EventLog& events, spdlog::logger& log) {
  OperatorAnswers out;
  for (const OperatorPrompt& p : prompts) {
    for (int attempt = 1;; ++attempt) {
      const std::string id = attempt == 1 ? p.id : fmt::format("{}-{}", p.id, attempt);
      events.write_note("prompt", {{"id", id}, {"text", p.text}, {"kind", p.kind}});
      log.info("operator prompt {}: {}", id, p.text);
      const auto answer = poller.wait_answer(id);
      if (!answer) return out;  // aborted while waiting
      events.write_note("prompt_answered", {{"id", id}, {"value", *answer}});
      std::string problem;
      if (p.kind == PromptKind::serial && *answer != unit_serial) {
        problem = fmt::format("the sensor reports serial \"{}\", not \"{}\"", unit_serial, *answer);
      } else if (p.kind == PromptKind::text && answer->empty()) {
        problem = "an answer is needed";
      }
      if (!problem.empty() && attempt < 5) {
        events.write_note("prompt_rejected", {{"id", id}, {"message", problem}});
        continue;
      }
      if (!problem.empty() || (p.kind == PromptKind::confirm && *answer != "yes")) {
        log.warn("operator prompt {}: {}; the run is aborted", id, problem.empty() ? "answered " + *answer : problem);
        control.abort.store(true);
        return out;
      }
      out.answers[p.id] = *answer;
      break;
    }
  }
  out.complete = true;
  out.signed_off_utc = utc_now_iso();
  return out;
}

}  // namespace fpss
