// The stand's recording format (samples CSV): a column-major table, its reader and an appending writer.
#pragma once
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fpss {

enum class Phase : uint8_t { null, offset, slew, move };
std::string_view to_string(Phase p);
std::optional<Phase> parse_phase(std::string_view s);

// One row of the contract's required columns.
struct Sample {
  double time_s = 0;  // stand time, physical seconds, non-decreasing
  Phase phase = Phase::null;
  int64_t step = 0;  // one per dwell or slew segment, increasing
  double ref_pitch_arcsec = 0;  // reference angles of the Sun in the sensor frame
  double ref_yaw_arcsec = 0;
  double counts_alpha = 0;  // sensor outputs (fractional when averaged)
  double counts_beta = 0;
};

// Two frames of one step whose reference angles both agree to the last digit share one encoder
// reading (a recorder that reads the gimbal less often than frames come). Two readings of a noisy
// encoder agree on both axes by chance rarely (0.05 arcsec of noise at 1 mas: about 4e-5 of the
// time), and then one reading is counted short.
inline bool same_reading(double pitch_a, double yaw_a, double pitch_b, double yaw_b) {
  return pitch_a == pitch_b && yaw_a == yaw_b;
}

// The columns a reduction reads of every frame, borrowed: a SampleTable's, or the leaner set the
// diagnosis reads a large file into. All of one length.
struct FrameColumns {
  const std::string& origin;
  const std::vector<double>& time_s;
  const std::vector<Phase>& phase;
  const std::vector<int64_t>& step;
  const std::vector<double>& ref_pitch_arcsec;
  const std::vector<double>& ref_yaw_arcsec;
  const std::vector<double>& counts_alpha;
  const std::vector<double>& counts_beta;
  // The sensor's temperature per row (samples.csv `temperature_c`, NaN where none); null: none.
  const std::vector<double>* temperature_c = nullptr;
  size_t size() const { return time_s.size(); }
  Sample row(size_t i) const {
    return Sample{time_s[i], phase[i], step[i], ref_pitch_arcsec[i], ref_yaw_arcsec[i], counts_alpha[i], counts_beta[i]};
  }
};

// Column-major so that two million rows stay compact. An extra column is numbers (a recorder's
// provenance, NaN for an empty cell) or text (a column read from a file, kept as written).
class SampleTable {
 public:
  static constexpr const char* kRequired[] = {"time_s", "phase", "step", "ref_pitch_arcsec",
                                              "ref_yaw_arcsec", "counts_alpha", "counts_beta"};

  size_t size() const { return time_s.size(); }
  bool empty() const { return time_s.empty(); }
  void reserve(size_t n);
  void push_back(const Sample& s);
  // Extras in the order of extra_names(); adds missing cells as "" (NaN). A numeric column takes
  // the text as a number (InputError naming the column for one that is not).
  void push_back(const Sample& s, const std::vector<std::string>& extras);
  // The same from numbers: a text column gets the number's shortest round-trip text ("" for NaN).
  void push_back(const Sample& s, const std::vector<double>& extras);
  Sample row(size_t i) const;
  // The required columns, borrowed.
  FrameColumns frames() const {
    return {origin, time_s, phase, step, ref_pitch_arcsec, ref_yaw_arcsec, counts_alpha, counts_beta};
  }
  // The rows of steps up to `last_step` (steps increase: a leading part of the table), every
  // column kept as it is (extras with their type), and the origin.
  SampleTable up_to_step(int64_t last_step) const;

  const std::vector<std::string>& extra_names() const { return extra_names_; }
  void add_extra_column(const std::string& name);    // text, filled with "" for existing rows
  void add_numeric_column(const std::string& name);  // numbers, filled with NaN for existing rows
  bool has_column(std::string_view name) const;
  // An extra column as text (a numeric one formatted as samples.csv writes it).
  std::vector<std::string> extra_column(std::string_view name) const;
  // One cell of the k-th extra column as samples.csv writes it.
  std::string extra_text(size_t k, size_t row) const;
  // An extra column as numbers; empty cells are NaN. Throws InputError naming the row.
  std::vector<double> numeric_column(std::string_view name) const;

  std::vector<double> time_s;
  std::vector<Phase> phase;
  std::vector<int64_t> step;
  std::vector<double> ref_pitch_arcsec, ref_yaw_arcsec;
  std::vector<double> counts_alpha, counts_beta;

  std::string origin;  // file it was read from, for messages

 private:
  struct Extra {
    bool numeric = false;
    std::vector<std::string> text;
    std::vector<double> numbers;
  };
  size_t extra_index(std::string_view name) const;  // InputError naming the table for none
  std::vector<std::string> extra_names_;
  std::vector<Extra> extra_;
};

// Reads a samples CSV. Throws InputError naming file, line and column for every format break:
// missing required column, non-numeric or non-finite value, unknown phase, time going backwards,
// step decreasing.
SampleTable read_samples_csv(const std::filesystem::path& path);
SampleTable parse_samples_csv(std::string_view text, const std::string& origin);

// Reads a samples CSV row by row without holding it: `on_row` gets every data row in order (the
// required columns). The same checks and messages as read_samples_csv (it parses the file in
// chunks of lines with parse_samples_csv, each chunk headed by the header and the row before it,
// so the order checks hold across chunks). Returns the number of rows.
size_t for_each_sample_csv(const std::filesystem::path& path, const std::function<void(const Sample&)>& on_row,
                           size_t chunk_lines = 4096);
// The same, a chunk at a time: `on_chunk` gets each chunk as a table (extra columns included),
// the index of its first new row (row 0 of a later chunk repeats the previous chunk's last row)
// and the fraction of the file read so far (for reserving).
size_t for_each_sample_chunk(
    const std::filesystem::path& path,
    const std::function<void(const SampleTable& chunk, size_t first_new, double fraction_read)>& on_chunk,
    size_t chunk_lines = 4096);

// Writes a whole table (required columns first, then extras).
void write_samples_csv(const std::filesystem::path& path, const SampleTable& t);

// Appends rows to a samples CSV; sync() makes what was appended durable (fsync), so a crash
// loses at most the rows after the last sync. Opening an existing file appends after checking
// its header matches.
class SamplesCsvWriter {
 public:
  SamplesCsvWriter(const std::filesystem::path& path, std::vector<std::string> extra_names);
  ~SamplesCsvWriter();
  SamplesCsvWriter(const SamplesCsvWriter&) = delete;
  SamplesCsvWriter& operator=(const SamplesCsvWriter&) = delete;

  void append(const Sample& s, const std::vector<std::string>& extras = {});
  void sync();
  size_t rows_written() const { return rows_; }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  std::vector<std::string> extra_names_;
  FILE* f_ = nullptr;
  size_t rows_ = 0;
};

// Formats a double the way the recorder writes it: shortest text that reads back exactly.
std::string format_number(double v);

}  // namespace fpss
