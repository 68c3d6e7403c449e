#include "procedures/recorder.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <sstream>

#include "base/clock.h"
#include "base/errors.h"
#include "base/text_file.h"
#include "base/unique_fd.h"

namespace fpss {

namespace fs = std::filesystem;

const std::vector<std::string>& recorder_extra_columns() {
  static const std::vector<std::string> c{
      "sensor_time_s", "frame_seq",  "sensor_status",        "host_time_s",         "gimbal_time_s",
      "gimbal_pitch_arcsec", "gimbal_yaw_arcsec", "gimbal_status", "target_pitch_arcsec", "target_yaw_arcsec",
      "temperature_c", "attempt",    "session", "time_since_move_s", "approach_pitch", "approach_yaw"};
  return c;
}

std::vector<double> RecordedRow::provenance() const {
  return {sensor_time_s, static_cast<double>(frame_seq), static_cast<double>(sensor_status), host_time_s, gimbal_time_s,
          gimbal_pitch_arcsec, gimbal_yaw_arcsec, static_cast<double>(gimbal_status), target_pitch_arcsec,
          target_yaw_arcsec, temperature_c, static_cast<double>(attempt), static_cast<double>(session),
          time_since_move_s, approach_pitch, approach_yaw};
}

std::vector<std::string> RecordedRow::extras() const {
  std::vector<std::string> out;
  for (const double v : provenance()) out.push_back(std::isfinite(v) ? format_number(v) : std::string());
  return out;
}

std::string utc_compact(const std::string& iso) {
  std::string s;
  for (char c : iso) if (c != '-' && c != ':') s += c;
  return s;
}

namespace {
std::string safe_name(const std::string& s) {
  std::string o;
  for (char c : s) o += (std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-') ? c : '_';
  return o.empty() ? "unknown" : o;
}

std::string header_text() {
  std::string h;
  for (const char* r : SampleTable::kRequired) {
    if (!h.empty()) h += ',';
    h += r;
  }
  for (const auto& e : recorder_extra_columns()) h += "," + e;
  return h + "\n";
}

void fsync_dir(const fs::path& dir) {
  const UniqueFd fd(::open(dir.c_str(), O_RDONLY | O_DIRECTORY));
  if (fd) ::fsync(fd.get());
}
}  // namespace

fs::path make_run_dir(const fs::path& runs_dir, const std::string& utc_iso, const std::string& unit,
                      const std::string& procedure) {
  fs::create_directories(runs_dir);
  const std::string base = fmt::format("{}-{}-{}", utc_compact(utc_iso), safe_name(unit), safe_name(procedure));
  for (int i = 1; i < 10000; ++i) {
    fs::path p = runs_dir / (i == 1 ? base : fmt::format("{}-{}", base, i));
    // create_directory is atomic: two runs starting in the same second get different folders.
    if (fs::create_directory(p)) return p;
  }
  throw std::runtime_error(fmt::format("{}: cannot create a run folder {}", runs_dir.string(), base));
}

void write_json_atomic(const fs::path& path, const nlohmann::json& j) { write_text_atomic(path, j.dump(2) + "\n"); }

std::vector<JournalEntry> RunRecorder::read_journal(const fs::path& path) {
  std::vector<JournalEntry> out;
  std::ifstream in(path, std::ios::binary);
  if (!in) return out;
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::string> lines;
  size_t pos = 0;
  while (pos < text.size()) {
    const size_t e = text.find('\n', pos);
    if (e == std::string::npos) break;  // torn last line: the point it described is not durable
    lines.push_back(text.substr(pos, e - pos));
    pos = e + 1;
  }
  for (size_t i = 0; i < lines.size(); ++i) {
    const std::string& line = lines[i];
    if (line.empty()) continue;
    const int line_no = static_cast<int>(i) + 1;
    JournalEntry je;
    try {
      auto j = nlohmann::json::parse(line);
      // The file numbers points from 1, as the step column does; an older journal numbered them
      // from 0 (point = step - 1). Either way the plan index is step - 1.
      const int64_t number = j.at("point").get<int64_t>();
      je.step = j.at("step").get<int64_t>();
      if (number != je.step && number != je.step - 1) {
        throw InputError(fmt::format("{}:{}: point {} does not match step {}", path.string(), line_no, number, je.step));
      }
      je.point = je.step - 1;
      je.rows = j.at("rows").get<size_t>();
      je.bytes = j.at("bytes").get<uint64_t>();
      je.last_time_s = j.at("last_time_s").get<double>();
      je.utc = j.value("utc", "");
      je.session = j.value("session", 1);
      je.attempts = j.value("attempts", 1);
      je.skipped = j.value("skipped", "");
      if (j.contains("unit_bytes")) {
        je.unit_bytes = j.at("unit_bytes").get<std::vector<uint64_t>>();
        if (je.unit_bytes.size() > 64) throw InputError(fmt::format("{}:{}: key unit_bytes: more than 64 units", path.string(), line_no));
      }
      if (je.skipped.size() > 200) throw InputError(fmt::format("{}:{}: key skipped: longer than 200 characters", path.string(), line_no));
    } catch (const nlohmann::json::exception& ex) {
      // The journal is not synced line by line (samples.csv is, before each line): a crash can
      // leave its last line unreadable, which only means that point is measured again.
      if (i + 1 == lines.size()) break;
      throw InputError(fmt::format("{}:{}: malformed journal line: {}", path.string(), line_no, ex.what()));
    }
    const int64_t expected = out.empty() ? 0 : out.back().point + 1;
    if (je.point != expected) {
      throw InputError(fmt::format("{}:{}: point {} follows point {}: the journal has a gap or a repeat",
                                   path.string(), line_no, je.point + 1, expected));
    }
    out.push_back(je);
  }
  return out;
}

namespace {
// Bytes of the journal's complete, readable lines (what read_journal accepted).
uint64_t journal_good_bytes(const fs::path& path, size_t entries) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return 0;
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  uint64_t pos = 0;
  size_t seen = 0;
  while (seen < entries && pos < text.size()) {
    const size_t e = text.find('\n', pos);
    if (e == std::string::npos) break;
    if (e > pos) ++seen;
    pos = e + 1;
  }
  return pos;
}
}  // namespace

std::string unit_folder_name(const std::string& serial) { return safe_name(serial); }

fs::path RunRecorder::samples_path(size_t unit) const {
  if (serials_.size() <= 1) return dir_ / "samples.csv";
  return dir_ / "units" / unit_folder_name(serials_.at(unit)) / "samples.csv";
}

void RunRecorder::open_samples(size_t unit, uint64_t keep) {
  const fs::path samples = samples_path(unit);
  fs::create_directories(samples.parent_path());
  if (fs::exists(samples)) {
    const uint64_t size = fs::file_size(samples);
    if (size < keep) {
      throw InputError(fmt::format("{}: {} bytes, but the journal {} says {} were synced: the recording was "
                                   "damaged outside the stand",
                                   samples.string(), size, journal_path().string(), keep));
    }
    if (size > keep) {
      cut_bytes_ += size - keep;
      fs::resize_file(samples, keep);
    }
  } else if (!journal_.empty()) {
    throw InputError(fmt::format("{}: missing, but the journal lists {} points", samples.string(), journal_.size()));
  }
  writers_.push_back(std::make_unique<SamplesCsvWriter>(samples, recorder_extra_columns()));
  fsync_dir(samples.parent_path());
}

RunRecorder::RunRecorder(const fs::path& run_dir, std::vector<std::string> unit_serials)
    : dir_(run_dir), serials_(std::move(unit_serials)) {
  if (serials_.size() == 1) serials_.clear();
  fs::create_directories(dir_);
  journal_ = read_journal(journal_path());
  // Cut the journal back to its readable lines (a torn line is a point that never completed).
  if (fs::exists(journal_path())) {
    const uint64_t good = journal_good_bytes(journal_path(), journal_.size());
    if (good != fs::file_size(journal_path())) fs::resize_file(journal_path(), good);
  }
  const uint64_t header = header_text().size();
  for (size_t u = 0; u < units(); ++u) {
    uint64_t keep = header;
    if (!journal_.empty()) {
      const JournalEntry& last = journal_.back();
      if (serials_.empty()) keep = last.bytes;
      else if (last.unit_bytes.size() == serials_.size()) keep = last.unit_bytes[u];
      else throw InputError(fmt::format("{}: the journal's unit_bytes list {} units, the run has {}",
                                        journal_path().string(), last.unit_bytes.size(), serials_.size()));
    }
    open_samples(u, keep);
  }
  if (!journal_.empty()) {
    last_time_s_ = journal_.back().last_time_s;
    for (const auto& j : journal_) has_rows_ = has_rows_ || j.rows > 0;
  }
  journal_fd_.reset(::open(journal_path().c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644));
  if (!journal_fd_) {
    throw std::runtime_error(fmt::format("{}: cannot open ({})", journal_path().string(), std::strerror(errno)));
  }
  fsync_dir(dir_);
}

RunRecorder::~RunRecorder() {
  if (journal_fd_) ::fsync(journal_fd_.get());  // closed by its owner
}

void RunRecorder::append_point(int64_t point, const std::vector<RecordedRow>& rows, int attempts, int session) {
  if (point != next_point()) {
    throw std::logic_error(fmt::format("recorder: point {} out of order (next is {})", point + 1, next_point() + 1));
  }
  for (const auto& r : rows) {
    const size_t u = serials_.empty() ? 0 : static_cast<size_t>(r.unit);
    if (u >= writers_.size()) throw std::logic_error(fmt::format("recorder: a row of unit {} (the run has {})", u + 1, writers_.size()));
    writers_[u]->append(r.sample, r.extras());
    last_time_s_ = std::max(last_time_s_, r.sample.time_s);
  }
  for (auto& w : writers_) w->sync();
  journal_point(point, rows.size(), attempts, session, {});
  has_rows_ = has_rows_ || !rows.empty();
}

void RunRecorder::skip_point(int64_t point, int session, const std::string& why) {
  if (point != next_point()) {
    throw std::logic_error(fmt::format("recorder: point {} out of order (next is {})", point + 1, next_point() + 1));
  }
  journal_point(point, 0, 0, session, why);
}

void RunRecorder::journal_point(int64_t point, size_t rows, int attempts, int session, const std::string& skipped) {
  JournalEntry je;
  je.point = point;
  je.step = point + 1;
  je.rows = rows;
  je.bytes = fs::file_size(samples_path());
  for (size_t u = 0; u < serials_.size(); ++u) je.unit_bytes.push_back(fs::file_size(samples_path(u)));
  je.last_time_s = last_time_s_;
  je.utc = utc_now_iso();
  je.session = session;
  je.attempts = attempts;
  je.skipped = skipped;
  nlohmann::json j{{"point", je.point + 1}, {"step", je.step},   {"rows", je.rows},
                   {"bytes", je.bytes},     {"last_time_s", je.last_time_s}, {"utc", je.utc},
                   {"session", je.session}, {"attempts", je.attempts}};
  if (!skipped.empty()) j["skipped"] = skipped;
  if (!je.unit_bytes.empty()) j["unit_bytes"] = je.unit_bytes;
  const std::string line = j.dump() + "\n";
  // No fsync here: samples.csv is durable already, and a journal line lost in a crash only
  // means the point is cut and measured again on resume (one fsync per point, not two).
  if (::write(journal_fd_.get(), line.data(), line.size()) != static_cast<ssize_t>(line.size())) {
    throw std::runtime_error(fmt::format("{}: journal write failed ({})", journal_path().string(),
                                         std::strerror(errno)));
  }
  journal_.push_back(je);
}

}  // namespace fpss
