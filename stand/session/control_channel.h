// The run folder's control channel (RUN_DIR/control.json): how the web console pauses, resumes and aborts a run and answers its prompts.
#pragma once
#include <atomic>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>
#include <spdlog/logger.h>

#include "procedures/engine.h"
#include "procedures/events.h"

namespace fpss {

// What the console asks of a run: the whole state, written atomically, so a request is never
// half-read and writing it twice is harmless (docs/console.md).
struct ControlRequest {
  bool pause = false;
  bool abort = false;
  std::map<std::string, std::string> answers;  // prompt id -> the operator's answer
};
inline constexpr std::uintmax_t kMaxControlFileBytes = 64 * 1024;
inline constexpr const char* kControlFile = "control.json";

// nullopt when the file is missing, too large, not a regular file or not the expected JSON.
std::optional<ControlRequest> read_control(const std::filesystem::path& run_dir);
void write_control(const std::filesystem::path& run_dir, const ControlRequest& c);

// A question the run asks the operator before anything moves (in the manner of OpenHTF's user input).
// What answer a prompt takes: serial (must equal the serial the sensor reports), confirm (yes or
// no; no aborts), text (not empty).
enum class PromptKind { serial, confirm, text };
// Its names in the prompt events and control.json (docs/console.md).
NLOHMANN_JSON_SERIALIZE_ENUM(PromptKind, {{PromptKind::serial, "serial"}, {PromptKind::confirm, "confirm"},
                                          {PromptKind::text, "text"}})

struct OperatorPrompt {
  std::string id;    // key of the answer in control.json and in the prompt events
  std::string text;  // what the operator reads
  PromptKind kind = PromptKind::text;
};

// Writes a clean RUN_DIR/control.json, then polls it every 50 ms on its own thread and applies changes to `control`:
// pause and resume when the console's pause flips, abort (StopCause::aborted: no signal) once.
// Other pausers (SIGUSR1, a terminal key) keep working: only a change in the file acts.
class ControlPoller {
 public:
  ControlPoller(std::filesystem::path run_dir, RunControl& control);
  ~ControlPoller();
  ControlPoller(const ControlPoller&) = delete;
  ControlPoller& operator=(const ControlPoller&) = delete;

  // Blocks until control.json answers prompt `id` (nullopt when the run is aborted meanwhile).
  std::optional<std::string> wait_answer(const std::string& id);

 private:
  void loop();
  std::filesystem::path dir_;
  RunControl& control_;
  std::atomic<bool> stop_{false};
  std::mutex m_;
  ControlRequest last_;
  std::thread thread_;
};

// Asks each prompt (an event in events.jsonl: "prompt", then "prompt_answered" or
// "prompt_rejected") and waits for its answer in control.json. Kind "serial" must equal
// `unit_serial` (asked again as "serial-2", ... up to 5 times), "confirm" must be "yes", "text" must
// not be empty; otherwise control.abort is set and `complete` is false.
struct OperatorAnswers {
  bool complete = false;
  std::map<std::string, std::string> answers;
  std::string signed_off_utc;  // when the last answer came
};
OperatorAnswers ask_operator(const std::vector<OperatorPrompt>& prompts, const std::string& unit_serial,
                             ControlPoller& poller, RunControl& control, EventLog& events, spdlog::logger& log);

}  // namespace fpss
