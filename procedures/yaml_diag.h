// Validation of YAML inputs that reports every problem at once, each with file:line:column.
#pragma once
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "base/text_file.h"

namespace fpss {

// A place in a text file, 1-based; line 0 means "the file as a whole".
struct TextMark {
  int line = 0;
  int column = 0;
  static TextMark of(const YAML::Node& n);
  static TextMark of(const YAML::Mark& m);
};

struct Diagnostic {
  std::string file;
  TextMark mark;
  std::string message;
  std::string str() const;  // "file:line:column: message"
};

// Collects errors instead of stopping at the first, so a user fixes a file in one pass.
class Diagnostics {
 public:
  explicit Diagnostics(std::string file) : file_(std::move(file)) {}

  void error(const TextMark& at, std::string message);
  void error(const YAML::Node& at, std::string message) { error(TextMark::of(at), std::move(message)); }
  // An error found in another file (a stand file seen while validating a procedure).
  void add(Diagnostic d) { all_.push_back(std::move(d)); }
  void merge(const Diagnostics& other);

  bool empty() const { return all_.empty(); }
  size_t size() const { return all_.size(); }
  const std::vector<Diagnostic>& all() const { return all_; }
  const std::string& file() const { return file_; }
  // One line per error, in the order found.
  std::string text() const;
  // Throws InputError carrying text() when there is any error.
  void throw_if_any() const;

 private:
  std::string file_;
  std::vector<Diagnostic> all_;
};

// Loads a YAML document; a syntax error becomes a diagnostic (returns a null node).
YAML::Node parse_yaml(std::string_view text, Diagnostics& d);
// The same for a file whose top must be a map: a top that is not one is an error at its place,
// "<expected>, got <what it is>", and gives a null node too.
YAML::Node parse_yaml_map(std::string_view text, Diagnostics& d, const std::string& expected);

// What a YAML node is, for "expected X, got Y" messages.
std::string describe_node(const YAML::Node& n);

// The documented range of a number field (docs/procedures.md, Limits), chosen by the unit its name
// ends with: every number MapReader reads is checked against it, whatever the caller then asks
// (positive, non-negative). Beyond it a value is a typo or an attack, never a stand setting.
struct NumberRange {
  double lo, hi;
};
NumberRange number_range(std::string_view key);

// Reads the fields of one YAML map with type checks; finish() reports every field nobody asked
// for as unknown, listing the known ones. `where` prefixes messages, e.g. "step 3 (move)".
class MapReader {
 public:
  MapReader(const YAML::Node& map, std::string where, Diagnostics& d);

  bool ok() const { return ok_; }  // the node was a map (or null, read as empty)
  bool has(const std::string& key) const;
  YAML::Node node(const std::string& key);  // marks known; null node when absent

  // Each returns nullopt when absent (reporting it when required) or of the wrong type.
  std::optional<double> number(const std::string& key, bool required = false);
  std::optional<double> positive(const std::string& key, bool required = false);      // > 0
  std::optional<double> non_negative(const std::string& key, bool required = false);  // >= 0
  std::optional<int64_t> integer(const std::string& key, bool required = false, int64_t min = INT64_MIN,
                                 int64_t max = INT64_MAX);
  std::optional<bool> boolean(const std::string& key, bool required = false);
  std::optional<std::string> string(const std::string& key, bool required = false);
  std::optional<std::string> choice(const std::string& key, std::initializer_list<std::string_view> options,
                                    bool required = false);
  // An angle given as <base>_deg or <base>_arcsec (exactly one), returned in arcsec.
  std::optional<double> angle_arcsec(const std::string& base, bool required = false);
  // A rate given as <base>_arcsec_s or <base>_deg_s, returned in arcsec/s.
  std::optional<double> rate_arcsec_s(const std::string& base, bool required = false);
  // A [min, max] pair of angles as <base>_deg or <base>_arcsec, in arcsec.
  std::optional<std::pair<double, double>> angle_range_arcsec(const std::string& base, bool required = false);
  // A [min, max] pair of plain numbers, each within number_range(key), min < max.
  std::optional<std::pair<double, double>> range(const std::string& key, bool required = false);

  void finish();  // unknown fields -> errors

  const std::string& where() const { return where_; }
  Diagnostics& diagnostics() { return d_; }
  TextMark mark() const { return TextMark::of(map_); }

  // Reads a scalar node as a number; reports "expected a number" otherwise, and a value outside
  // number_range(key) as out of range.
  static std::optional<double> as_number(const YAML::Node& n, const std::string& what, Diagnostics& d,
                                         std::string_view key = {});

 private:
  void missing(const std::string& what);
  // node(key), having reported it missing when required and absent.
  YAML::Node field(const std::string& key, bool required);
  std::optional<std::pair<std::string, double>> pick_unit(const std::string& base,
                                                          std::initializer_list<std::pair<const char*, double>> units,
                                                          bool required);

  YAML::Node map_;
  std::string where_;
  Diagnostics& d_;
  bool ok_ = true;
  std::set<std::string> known_;
};

// Reads a YAML file of ours (procedure, stand) through `parse(text, origin, diagnostics)`: a
// regular file of at most kMaxConfigFileBytes; throws InputError listing every error.
template <class Parse>
auto load_yaml_file(const std::filesystem::path& path, std::string_view what, Parse parse) {
  const std::string text = read_text_file(path, what, kMaxConfigFileBytes);
  Diagnostics d(path.string());
  auto value = parse(text, path.string(), d);
  d.throw_if_any();
  return value;
}

}  // namespace fpss
