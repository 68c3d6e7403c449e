#include "stand/console/run_files.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <utility>

#include "base/json_file.h"
#include "base/text_file.h"
#include "base/unique_fd.h"
#include "stand/catalogue/catalogue.h"
#include "stand/catalogue/run_file.h"
#include "stand/console/jobs.h"

namespace fpss::console {

namespace fs = std::filesystem;

namespace {

RunRef ref_of(const RunRecord& r) {
  RunRef x;
  x.run_id = r.run_id;
  x.dir = r.run_dir;
  x.pid = static_cast<int>(r.pid);
  x.live = r.running() && run_alive(r.run_dir, r.pid);
  return x;
}

// run.json, typed; empty when the folder has none or it does not read (a run being written, moved).
std::optional<RunFile> read_run(const fs::path& dir) {
  try {
    return read_run_file(dir);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace

std::optional<RunRef> find_run(CataloguePool& catalogue, const std::string& run_id) {
  if (!safe_name(run_id, 200)) return std::nullopt;
  auto cat = catalogue.acquire();
  if (!cat) return std::nullopt;
  auto r = cat->find_run(run_id);
  if (!r) return std::nullopt;
  return ref_of(*r);
}

std::vector<RunRef> live_runs(CataloguePool& catalogue) {
  std::vector<RunRef> out;
  auto cat = catalogue.acquire();
  if (!cat) return out;
  RunFilter f;
  f.limit = 50;
  for (const auto& r : cat->list_runs(f)) {
    if (RunRef x = ref_of(r); x.live) out.push_back(std::move(x));
  }
  return out;
}

std::optional<RunRef> run_of_pid(CataloguePool& catalogue, int pid, const std::string& spawned_utc) {
  auto cat = catalogue.acquire();
  if (!cat) return std::nullopt;
  RunFilter f;
  f.limit = 20;
  for (const auto& r : cat->list_runs(f)) {
    // Both times are ISO 8601 UTC to the second (YYYY-MM-DDTHH:MM:SSZ): they compare as text.
    if (r.pid == pid && r.started_utc >= spawned_utc) return ref_of(r);
  }
  return std::nullopt;
}

nlohmann::json runs_json(CataloguePool& catalogue, const std::string& unit, const std::string& outcome,
                         const std::string& from_date, const std::string& to_date, size_t limit) {
  nlohmann::json out = nlohmann::json::array();
  auto cat = catalogue.acquire();
  if (!cat) return out;
  RunFilter f;
  if (!unit.empty()) f.unit = unit;
  for (const auto& r : cat->list_runs(f)) {
    const RunRef ref = ref_of(r);
    std::string oc = r.running() && !ref.live ? "stale" : r.outcome_name();
    const std::optional<RunFile> run = read_run(r.run_dir);
    if (run && run->stop_cause == StopCause::aborted) oc = "aborted";
    if (!outcome.empty() && oc != outcome && r.outcome_name() != outcome) continue;
    const std::string day = r.started_utc.substr(0, 10);
    if (!from_date.empty() && day < from_date) continue;
    if (!to_date.empty() && day > to_date) continue;
    nlohmann::json j{{"run_id", r.run_id}, {"unit", r.unit},        {"procedure", r.procedure},
                     {"started_utc", r.started_utc}, {"ended_utc", r.ended_utc ? nlohmann::json(*r.ended_utc) : nlohmann::json()},
                     {"outcome", oc},   {"live", ref.live},       {"emulated", r.emulated}};
    if (run) {
      j["points"] = to_json(*run)["points"];
      if (const auto v = acceptance_verdict(*run)) j["verdict"] = *v;
      if (run->operator_name) j["operator"] = *run->operator_name;
    }
    out.push_back(j);
    if (limit && out.size() >= limit) break;
  }
  return out;
}

// The files a run's page links (a unit's folder has the same but the run's own two), and an
// investigation's.
constexpr const char* kUnitFiles[] = {"report.html", "GAP.html", "certificate.txt", "acceptance.json", "samples.csv",
                                      "calibration.json"};
constexpr const char* kRunOnlyFiles[] = {"events.jsonl", "run.json"};
constexpr const char* kInvestigationFiles[] = {"INVESTIGATION.html", "INVESTIGATION.json", "GAP.json", "GAP.html"};

// Those of `names` present under `rel_dir` of `dir`, by name, as the console serves them (`url`:
// where it serves `dir`).
static nlohmann::json served_files(const fs::path& dir, const std::string& url, const std::string& rel_dir,
                                   const auto& names) {
  nlohmann::json out = nlohmann::json::object();
  for (const char* f : names) {
    const std::string rel = rel_dir.empty() ? std::string(f) : rel_dir + "/" + f;
    if (run_file(dir, rel)) out[f] = url + "/" + rel;
  }
  return out;
}

nlohmann::json run_json(const RunRef& r) {
  const std::optional<RunFile> run = read_run(r.dir);
  const nlohmann::json doc = run ? to_json(*run) : nlohmann::json::object();
  nlohmann::json j{{"run_id", r.run_id}, {"live", r.live}};
  for (const char* k : {"unit", "procedure", "outcome", "stop_cause", "reason", "started_utc", "ended_utc", "points",
                        "safe_state", "operator", "signed_off_utc", "acceptance", "emulated"}) {
    if (doc.contains(k)) j[k] = doc[k];
  }
  if (j.contains("procedure") && j["procedure"].is_object()) j["procedure"].erase("text");
  const std::string url = "/runs/" + r.run_id;
  nlohmann::json files = served_files(r.dir, url, "", kUnitFiles);
  files.update(served_files(r.dir, url, "", kRunOnlyFiles));
  j["files"] = files;
  if (run && run->units) {
    // Several units: each one's outcome, verdict and files (units/<SERIAL>/...), and its pose.
    j["units"] = nlohmann::json::array();
    for (const RunFileUnit& u : *run->units) {
      nlohmann::json e = to_json(u);
      e["files"] = u.samples ? served_files(r.dir, url, fs::path(*u.samples).parent_path().string(), kUnitFiles)
                             : nlohmann::json::object();
      j["units"].push_back(e);
    }
  }
  return j;
}


EventChunk read_events(const fs::path& run_dir, uint64_t offset, size_t max_bytes) {
  EventChunk c;
  c.next = offset;
  const UniqueFd fd(::open((run_dir / "events.jsonl").c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW));
  if (!fd) return c;
  struct stat st {};
  if (::fstat(fd.get(), &st) != 0 || !S_ISREG(st.st_mode) || static_cast<uint64_t>(st.st_size) <= offset) return c;
  std::string buf(std::min<uint64_t>(max_bytes, static_cast<uint64_t>(st.st_size) - offset), '\0');
  const ssize_t n = ::pread(fd.get(), buf.data(), buf.size(), static_cast<off_t>(offset));
  if (n <= 0) return c;
  buf.resize(static_cast<size_t>(n));
  size_t start = 0;
  for (size_t nl = buf.find('\n'); nl != std::string::npos; nl = buf.find('\n', start)) {
    c.lines.push_back(buf.substr(start, nl - start));
    start = nl + 1;
    c.ends.push_back(offset + start);
  }
  // A line longer than the whole chunk can never complete here: skip it rather than stall.
  if (c.lines.empty() && buf.size() == max_bytes) c.next = offset + buf.size();
  else c.next = offset + start;
  return c;
}

std::optional<fs::path> investigation_dir(const fs::path& runs_dir, const std::string& name) {
  if (name.rfind("investigation-", 0) != 0 || !safe_name(name, 128)) return std::nullopt;
  const fs::path p = runs_dir / name;
  struct stat st {};
  if (::lstat(p.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) return std::nullopt;
  return p;
}

nlohmann::json investigations_json(const fs::path& runs_dir, size_t limit) {
  std::vector<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(runs_dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string n = it->path().filename().string();
    if (investigation_dir(runs_dir, n)) names.push_back(n);
  }
  std::sort(names.rbegin(), names.rend());
  nlohmann::json out = nlohmann::json::array();
  for (const auto& n : names) {
    if (out.size() >= limit) break;
    const fs::path dir = runs_dir / n;
    // A record is some kilobytes (a few runs and one diagnosis): a larger one is not read, so that a
    // listing of up to `limit` of them stays bounded.
    constexpr std::uintmax_t kMaxRecordBytes = std::uintmax_t{2} << 20;
    if (!run_file(dir, "INVESTIGATION.json")) continue;
    nlohmann::json inv;
    try {
      inv = read_json_file(dir / "INVESTIGATION.json", "INVESTIGATION.json", kMaxRecordBytes);
    } catch (const std::exception&) {
      continue;
    }
    if (!inv.is_object()) continue;
    nlohmann::json j{{"name", n}};
    for (const char* k : {"stop_reason", "stop_sentence", "verdict", "verdict_sentence", "no_diagnosis", "cause", "unbounded",
                          "bench_time_s"}) {
      if (inv.contains(k)) j[k] = inv[k];
    }
    nlohmann::json causes = nlohmann::json::array(), ambiguous = nlohmann::json::array(), runs = nlohmann::json::array();
    for (const auto& c : inv.value("causes", nlohmann::json::array())) {
      if (c.is_object()) causes.push_back({{"name", c.value("name", "")}, {"params", c.value("params", nlohmann::json::object())}});
    }
    for (const auto& a : inv.value("ambiguous", nlohmann::json::array())) {
      if (a.is_object()) ambiguous.push_back(a.value("members", nlohmann::json::array()));
    }
    // The run folders by their ids (the folder's name is the run id), for the console's run pages.
    for (const auto& r : inv.value("runs", nlohmann::json::array())) {
      if (r.is_string()) runs.push_back(fs::path(r.get<std::string>()).filename().string());
    }
    j["causes"] = causes;
    j["ambiguous"] = ambiguous;
    j["runs"] = runs;
    j["files"] = served_files(dir, "/investigations/" + n, "", kInvestigationFiles);
    out.push_back(std::move(j));
  }
  return out;
}

std::optional<fs::path> run_file(const fs::path& run_dir, const std::string& rel) {
  if (rel.empty() || rel.size() > 300) return std::nullopt;
  fs::path p = run_dir;
  size_t start = 0;
  while (start <= rel.size()) {
    const size_t slash = rel.find('/', start);
    const std::string seg = rel.substr(start, slash == std::string::npos ? std::string::npos : slash - start);
    if (!safe_name(seg, 128)) return std::nullopt;
    p /= seg;
    if (slash == std::string::npos) break;
    start = slash + 1;
  }
  struct stat st {};
  if (::lstat(p.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return std::nullopt;
  return p;
}

}  // namespace fpss::console
