#include "calib/samples.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <array>
#include <charconv>
#include <cerrno>
#include <cmath>
#include <type_traits>
#include <cstring>
#include <fstream>
#include <limits>

#include "base/errors.h"
#include "base/text_file.h"

namespace fpss {

std::string_view to_string(Phase p) {
  switch (p) {
    case Phase::null: return "null";
    case Phase::offset: return "offset";
    case Phase::slew: return "slew";
    case Phase::move: return "move";
  }
  return "?";
}

std::optional<Phase> parse_phase(std::string_view s) {
  if (s == "null") return Phase::null;
  if (s == "offset") return Phase::offset;
  if (s == "slew") return Phase::slew;
  if (s == "move") return Phase::move;
  return std::nullopt;
}

namespace {

bool parse_double(std::string_view s, double& out) {
  while (!s.empty() && s.front() == ' ') s.remove_prefix(1);
  while (!s.empty() && s.back() == ' ') s.remove_suffix(1);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && p == s.data() + s.size() && std::isfinite(out);
}

}  // namespace

void SampleTable::reserve(size_t n) {
  time_s.reserve(n); phase.reserve(n); step.reserve(n);
  ref_pitch_arcsec.reserve(n); ref_yaw_arcsec.reserve(n);
  counts_alpha.reserve(n); counts_beta.reserve(n);
  for (auto& c : extra_) {
    c.numbers.reserve(c.numeric ? n : 0);
    c.text.reserve(c.numeric ? 0 : n);
  }
}

void SampleTable::push_back(const Sample& s) {
  time_s.push_back(s.time_s); phase.push_back(s.phase); step.push_back(s.step);
  ref_pitch_arcsec.push_back(s.ref_pitch_arcsec); ref_yaw_arcsec.push_back(s.ref_yaw_arcsec);
  counts_alpha.push_back(s.counts_alpha); counts_beta.push_back(s.counts_beta);
  for (auto& c : extra_) {
    if (c.numeric) c.numbers.push_back(std::numeric_limits<double>::quiet_NaN());
    else c.text.emplace_back();
  }
}

void SampleTable::push_back(const Sample& s, const std::vector<std::string>& extras) {
  // Every cell is read before anything is added: a bad one leaves the table as it was.
  std::vector<double> numbers(extra_.size(), std::numeric_limits<double>::quiet_NaN());
  for (size_t i = 0; i < extra_.size() && i < extras.size(); ++i) {
    if (extra_[i].numeric && !extras[i].empty() && !parse_double(extras[i], numbers[i])) {
      throw InputError(fmt::format("{}: data row {}, column \"{}\": expected a number, got \"{}\"", origin,
                                   size() + 1, extra_names_[i], extras[i]));
    }
  }
  push_back(s);
  for (size_t i = 0; i < extra_.size() && i < extras.size(); ++i) {
    if (extra_[i].numeric) extra_[i].numbers.back() = numbers[i];
    else extra_[i].text.back() = extras[i];
  }
}

void SampleTable::push_back(const Sample& s, const std::vector<double>& extras) {
  push_back(s);
  for (size_t i = 0; i < extra_.size() && i < extras.size(); ++i) {
    Extra& c = extra_[i];
    if (c.numeric) c.numbers.back() = extras[i];
    else c.text.back() = std::isfinite(extras[i]) ? format_number(extras[i]) : std::string();
  }
}

SampleTable SampleTable::up_to_step(int64_t last_step) const {
  size_t n = 0;
  while (n < size() && step[n] <= last_step) ++n;
  const auto head = [n](const auto& v) { return std::decay_t<decltype(v)>(v.begin(), v.begin() + static_cast<long>(n)); };
  SampleTable t;
  t.origin = origin;
  t.time_s = head(time_s);
  t.phase = head(phase);
  t.step = head(step);
  t.ref_pitch_arcsec = head(ref_pitch_arcsec);
  t.ref_yaw_arcsec = head(ref_yaw_arcsec);
  t.counts_alpha = head(counts_alpha);
  t.counts_beta = head(counts_beta);
  t.extra_names_ = extra_names_;
  for (const Extra& c : extra_) {
    t.extra_.push_back(Extra{c.numeric, c.numeric ? std::vector<std::string>() : head(c.text),
                             c.numeric ? head(c.numbers) : std::vector<double>()});
  }
  return t;
}

Sample SampleTable::row(size_t i) const {
  return Sample{time_s[i], phase[i], step[i], ref_pitch_arcsec[i], ref_yaw_arcsec[i],
                counts_alpha[i], counts_beta[i]};
}

void SampleTable::add_extra_column(const std::string& name) {
  if (has_column(name)) throw InputError(fmt::format("{}: duplicate column \"{}\"", origin, name));
  extra_names_.push_back(name);
  extra_.push_back(Extra{false, std::vector<std::string>(size()), {}});
}

void SampleTable::add_numeric_column(const std::string& name) {
  if (has_column(name)) throw InputError(fmt::format("{}: duplicate column \"{}\"", origin, name));
  extra_names_.push_back(name);
  extra_.push_back(Extra{true, {}, std::vector<double>(size(), std::numeric_limits<double>::quiet_NaN())});
}

bool SampleTable::has_column(std::string_view name) const {
  for (const char* r : kRequired) if (name == r) return true;
  for (const auto& n : extra_names_) if (n == name) return true;
  return false;
}

size_t SampleTable::extra_index(std::string_view name) const {
  for (size_t i = 0; i < extra_names_.size(); ++i) if (extra_names_[i] == name) return i;
  throw InputError(fmt::format("{}: no column \"{}\"", origin, name));
}

std::string SampleTable::extra_text(size_t k, size_t row) const {
  const Extra& c = extra_[k];
  if (!c.numeric) return c.text[row];
  return std::isfinite(c.numbers[row]) ? format_number(c.numbers[row]) : std::string();
}

std::vector<std::string> SampleTable::extra_column(std::string_view name) const {
  const size_t k = extra_index(name);
  if (!extra_[k].numeric) return extra_[k].text;
  std::vector<std::string> out(size());
  for (size_t i = 0; i < size(); ++i) out[i] = extra_text(k, i);
  return out;
}

namespace {


// Splits one CSV record (RFC 4180 quoting) into fields; returns false on an unterminated quote.
bool split_csv(std::string_view line, std::vector<std::string>& fields) {
  // Most lines quote nothing: each field is assigned in place, so its buffer serves row after row.
  if (line.find('"') == std::string_view::npos) {
    size_t n = 0;
    for (size_t start = 0;; ++n) {
      const size_t comma = line.find(',', start);
      const std::string_view piece = line.substr(start, comma == std::string_view::npos ? line.npos : comma - start);
      if (n < fields.size()) {
        fields[n].assign(piece);
      } else {
        fields.emplace_back(piece);
      }
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    fields.resize(n + 1);
    return true;
  }
  fields.clear();
  std::string cur;
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char ch = line[i];
    if (quoted) {
      if (ch == '"') {
        if (i + 1 < line.size() && line[i + 1] == '"') { cur += '"'; ++i; }
        else quoted = false;
      } else {
        cur += ch;
      }
    } else if (ch == '"') {
      quoted = true;
    } else if (ch == ',') {
      fields.push_back(std::move(cur));
      cur.clear();
    } else {
      cur += ch;
    }
  }
  fields.push_back(std::move(cur));
  return !quoted;
}

std::string csv_escape(const std::string& s) {
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string o = "\"";
  for (char c : s) { if (c == '"') o += '"'; o += c; }
  return o + '"';
}

}  // namespace

std::vector<double> SampleTable::numeric_column(std::string_view name) const {
  const size_t k = extra_index(name);
  if (extra_[k].numeric) return extra_[k].numbers;
  const auto& col = extra_[k].text;
  std::vector<double> v(col.size());
  for (size_t i = 0; i < col.size(); ++i) {
    if (col[i].empty()) { v[i] = std::numeric_limits<double>::quiet_NaN(); continue; }
    if (!parse_double(col[i], v[i])) {
      throw InputError(fmt::format("{}: data row {}, column \"{}\": expected a number, got \"{}\"",
                                   origin, i + 1, name, col[i]));
    }
  }
  return v;
}

namespace {
// The largest magnitude of each required numeric column (docs/formats.md, Limits): a day of stand
// time many times over, half a turn of reference angle, the counts' 16-bit range with margin.
// Beyond these a value is a corrupt file, and sums of squares of it would overflow.
constexpr double kSampleLimit[] = {1e9, 0, 0, 648000.0, 648000.0, 1e6, 1e6};
}  // namespace

SampleTable parse_samples_csv(std::string_view text, const std::string& origin) {
  SampleTable t;
  t.origin = origin;
  size_t pos = 0, line_no = 0;
  auto next_line = [&](std::string_view& line) {
    if (pos >= text.size()) return false;
    size_t e = text.find('\n', pos);
    if (e == std::string_view::npos) e = text.size();
    line = text.substr(pos, e - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos = e + 1;
    ++line_no;
    return true;
  };
  // A UTF-8 byte order mark (spreadsheets write one) is not part of the first column's name.
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
  std::string_view line;
  // Header: the first line that is neither blank nor a '#' comment.
  do {
    if (!next_line(line)) throw InputError(fmt::format("{}: empty file, expected a header row", origin));
  } while (line.empty() || line.front() == '#');
  std::vector<std::string> header;
  split_csv(line, header);
  constexpr size_t kReq = std::size(SampleTable::kRequired);
  std::array<int, kReq> col{};
  col.fill(-1);
  std::vector<int> extra_of(header.size(), -1);
  for (size_t i = 0; i < header.size(); ++i) {
    bool req = false;
    for (size_t r = 0; r < kReq; ++r) {
      if (header[i] == SampleTable::kRequired[r]) {
        if (col[r] >= 0) {
          throw InputError(fmt::format("{}:{}: column \"{}\" appears twice", origin, line_no, header[i]));
        }
        col[r] = static_cast<int>(i);
        req = true;
      }
    }
    if (!req) {
      extra_of[i] = static_cast<int>(t.extra_names().size());
      t.add_extra_column(header[i]);
    }
  }
  for (size_t r = 0; r < kReq; ++r) {
    if (col[r] < 0) {
      throw InputError(fmt::format("{}:{}: missing required column \"{}\" (header must name {})", origin,
                                   line_no, SampleTable::kRequired[r],
                                   "time_s, phase, step, ref_pitch_arcsec, ref_yaw_arcsec, counts_alpha, counts_beta"));
    }
  }
  t.reserve(text.size() / 48);
  std::vector<std::string> f;
  std::vector<std::string> extras(t.extra_names().size());
  while (next_line(line)) {
    if (line.empty() || line.front() == '#') continue;
    auto bad = [&](size_t r, const std::string& what) {
      return InputError(fmt::format("{}:{}: column \"{}\": {}", origin, line_no, SampleTable::kRequired[r], what));
    };
    if (!split_csv(line, f)) throw InputError(fmt::format("{}:{}: unterminated quote", origin, line_no));
    if (f.size() != header.size()) {
      throw InputError(fmt::format("{}:{}: expected {} fields as in the header, got {}", origin, line_no,
                                   header.size(), f.size()));
    }
    Sample s;
    double* num[] = {&s.time_s, nullptr, nullptr, &s.ref_pitch_arcsec, &s.ref_yaw_arcsec,
                     &s.counts_alpha, &s.counts_beta};
    for (size_t r = 0; r < kReq; ++r) {
      const std::string& v = f[col[r]];
      if (r == 1) {
        auto p = parse_phase(v);
        if (!p) throw bad(r, fmt::format("expected null, offset, slew or move, got \"{}\"", v));
        s.phase = *p;
      } else if (r == 2) {
        int64_t step = 0;
        auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), step);
        if (ec != std::errc() || p != v.data() + v.size()) throw bad(r, fmt::format("expected an integer, got \"{}\"", v));
        s.step = step;
      } else if (!parse_double(v, *num[r])) {
        throw bad(r, fmt::format("expected a finite number, got \"{}\"", v));
      } else if (std::abs(*num[r]) > kSampleLimit[r]) {
        throw bad(r, fmt::format("{} is beyond +-{:g} (docs/formats.md, Limits)", v, kSampleLimit[r]));
      }
    }
    if (!t.empty()) {
      if (s.time_s < t.time_s.back()) {
        throw bad(0, fmt::format("time goes backwards ({} after {})", s.time_s, t.time_s.back()));
      }
      if (s.step < t.step.back()) {
        throw bad(2, fmt::format("step decreases ({} after {}); steps must increase", s.step, t.step.back()));
      }
    }
    for (size_t i = 0; i < header.size(); ++i) if (extra_of[i] >= 0) extras[extra_of[i]] = std::move(f[i]);
    t.push_back(s, extras);
  }
  return t;
}

SampleTable read_samples_csv(const std::filesystem::path& path) {
  return parse_samples_csv(read_text_file(path, "samples file"), path.string());
}

namespace {

// parse_samples_csv on a chunk names chunk lines: 1 the header, 2 the carried row (when there is
// one), 3.. the chunk's own lines. Rewrites "<origin>:<n>:" to the file's line.
[[noreturn]] void rethrow_at_file_line(const InputError& e, const std::string& origin, size_t header_line,
                                       size_t carry_line, size_t first_line, bool carried) {
  const std::string m = e.what();
  const std::string prefix = origin + ":";
  size_t n = 0, p = prefix.size();
  if (m.compare(0, prefix.size(), prefix) == 0) {
    while (p < m.size() && m[p] >= '0' && m[p] <= '9') n = n * 10 + static_cast<size_t>(m[p++] - '0');
  }
  if (n == 0 || p >= m.size() || m[p] != ':') throw e;
  const size_t own = carried ? 3 : 2;
  const size_t line = n == 1 ? header_line : (carried && n == 2) ? carry_line : first_line + (n - own);
  throw InputError(fmt::format("{}{}{}", prefix, line, m.substr(p)));
}

}  // namespace

size_t for_each_sample_csv(const std::filesystem::path& path, const std::function<void(const Sample&)>& on_row,
                           size_t chunk_lines) {
  return for_each_sample_chunk(
      path,
      [&](const SampleTable& t, size_t first, double) {
        for (size_t i = first; i < t.size(); ++i) on_row(t.row(i));
      },
      chunk_lines);
}

size_t for_each_sample_chunk(
    const std::filesystem::path& path,
    const std::function<void(const SampleTable& chunk, size_t first_new, double fraction_read)>& on_chunk,
    size_t chunk_lines) {
  const std::string origin = path.string();
  check_input_file(path, "samples file", kMaxTextFileBytes);
  std::error_code size_ec;
  const double file_bytes = static_cast<double>(std::filesystem::file_size(path, size_ec));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot open {}: {}", origin, "samples file", std::strerror(errno)));
  std::string line, header;
  size_t line_no = 0, header_line = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!line.empty() && line.front() != '#') {
      header = line;
      header_line = line_no;
      break;
    }
  }
  if (header.empty()) parse_samples_csv(std::string_view(), origin);  // its "empty file" message
  try {
    parse_samples_csv(header + "\n", origin);  // the header's own checks
  } catch (const InputError& e) {
    rethrow_at_file_line(e, origin, header_line, 0, 0, false);
  }
  std::string carry;  // the last data row of the previous chunk, for the order checks
  size_t carry_line = 0, rows = 0;
  std::string chunk;
  for (bool more = true; more;) {
    chunk = header + "\n";
    const bool carried = !carry.empty();
    if (carried) chunk += carry + "\n";
    const size_t first_line = line_no + 1;
    size_t taken = 0;
    std::string last;
    size_t last_line = 0;
    while (taken < chunk_lines && (more = static_cast<bool>(std::getline(in, line)))) {
      ++line_no;
      ++taken;
      chunk += line;
      chunk += '\n';
      std::string_view l(line);
      if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
      if (!l.empty() && l.front() != '#') {
        last = line;
        last_line = line_no;
      }
    }
    if (taken == 0) break;
    SampleTable t;
    try {
      t = parse_samples_csv(chunk, origin);
    } catch (const InputError& e) {
      rethrow_at_file_line(e, origin, header_line, carry_line, first_line, carried);
    }
    const auto pos = in.tellg();
    const double read = in.eof() || pos < 0 || size_ec || file_bytes <= 0 ? 1.0 : static_cast<double>(pos) / file_bytes;
    on_chunk(t, carried ? 1 : 0, std::clamp(read, 1e-9, 1.0));
    rows += t.size() - (carried ? 1 : 0);
    if (!last.empty()) {
      carry = std::move(last);
      carry_line = last_line;
    }
  }
  return rows;
}

std::string format_number(double v) {
  char buf[64];
  auto [p, ec] = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, p);
}

namespace {
std::string header_line(const std::vector<std::string>& extra_names) {
  std::string h;
  for (const char* r : SampleTable::kRequired) { if (!h.empty()) h += ','; h += r; }
  for (const auto& n : extra_names) h += ',' + csv_escape(n);
  return h + '\n';
}

std::string row_line(const Sample& s, const std::vector<std::string>& extras, size_t n_extra) {
  std::string l = format_number(s.time_s);
  l += ','; l += to_string(s.phase);
  l += ','; l += std::to_string(s.step);
  for (double v : {s.ref_pitch_arcsec, s.ref_yaw_arcsec, s.counts_alpha, s.counts_beta}) {
    l += ','; l += format_number(v);
  }
  for (size_t i = 0; i < n_extra; ++i) { l += ','; if (i < extras.size()) l += csv_escape(extras[i]); }
  return l + '\n';
}
}  // namespace

void write_samples_csv(const std::filesystem::path& path, const SampleTable& t) {
  // Whole or not at all: a full disk leaves no truncated CSV (and no temporary file).
  AtomicFile out(path);
  std::string chunk = header_line(t.extra_names());
  std::vector<std::string> extras(t.extra_names().size());
  for (size_t i = 0; i < t.size(); ++i) {
    for (size_t k = 0; k < extras.size(); ++k) extras[k] = t.extra_text(k, i);
    chunk += row_line(t.row(i), extras, extras.size());
    if (chunk.size() >= (1u << 20)) {
      out.write(chunk);
      chunk.clear();
    }
  }
  out.write(chunk);
  out.commit();
}

SamplesCsvWriter::SamplesCsvWriter(const std::filesystem::path& path, std::vector<std::string> extra_names)
    : path_(path), extra_names_(std::move(extra_names)) {
  const std::string header = header_line(extra_names_);
  const bool exists = std::filesystem::exists(path) && std::filesystem::file_size(path) > 0;
  if (exists) {
    std::ifstream in(path);
    std::string first;
    std::getline(in, first);
    if (first + '\n' != header) {
      throw InputError(fmt::format("{}: cannot append, header differs from the recorder's ({})", path.string(), first));
    }
    std::string l;
    while (std::getline(in, l)) if (!l.empty()) ++rows_;
  }
  // O_NOFOLLOW: a symlink planted at the recording's path is never followed.
  const int fd = ::open(path.c_str(), O_WRONLY | O_APPEND | O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0 || !(f_ = ::fdopen(fd, "ab"))) {
    const std::string why = std::strerror(errno);
    if (fd >= 0) ::close(fd);
    throw std::runtime_error(fmt::format("{}: cannot open for append: {}", path.string(), why));
  }
  if (!exists) {
    std::fputs(header.c_str(), f_);
    sync();
  }
}

SamplesCsvWriter::~SamplesCsvWriter() {
  if (f_) {
    sync();
    std::fclose(f_);
  }
}

void SamplesCsvWriter::append(const Sample& s, const std::vector<std::string>& extras) {
  const std::string l = row_line(s, extras, extra_names_.size());
  if (std::fwrite(l.data(), 1, l.size(), f_) != l.size()) {
    throw std::runtime_error(fmt::format("{}: write failed", path_.string()));
  }
  ++rows_;
}

void SamplesCsvWriter::sync() {
  if (std::fflush(f_) != 0 || ::fsync(fileno(f_)) != 0) {
    throw std::runtime_error(fmt::format("{}: sync failed", path_.string()));
  }
}

}  // namespace fpss
