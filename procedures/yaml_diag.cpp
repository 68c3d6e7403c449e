#include "procedures/yaml_diag.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <tuple>
#include <string>

#include "base/errors.h"

namespace fpss {

TextMark TextMark::of(const YAML::Mark& m) {
  if (m.line < 0) return {};
  return {m.line + 1, m.column + 1};
}

TextMark TextMark::of(const YAML::Node& n) {
  if (!n.IsDefined()) return {};
  return of(n.Mark());
}

std::string Diagnostic::str() const {
  if (mark.line <= 0) return fmt::format("{}: {}", file, message);
  return fmt::format("{}:{}:{}: {}", file, mark.line, mark.column, message);
}

void Diagnostics::error(const TextMark& at, std::string message) {
  all_.push_back(Diagnostic{file_, at, std::move(message)});
}

void Diagnostics::merge(const Diagnostics& other) {
  for (const auto& d : other.all()) all_.push_back(d);
}

std::string Diagnostics::text() const {
  // In reading order: file by file (as first met), then line and column.
  std::vector<std::string> files;
  for (const auto& d : all_) if (std::find(files.begin(), files.end(), d.file) == files.end()) files.push_back(d.file);
  auto rank = [&](const Diagnostic& d) { return std::find(files.begin(), files.end(), d.file) - files.begin(); };
  std::vector<Diagnostic> sorted = all_;
  std::stable_sort(sorted.begin(), sorted.end(), [&](const Diagnostic& a, const Diagnostic& b) {
    return std::tuple(rank(a), a.mark.line, a.mark.column) < std::tuple(rank(b), b.mark.line, b.mark.column);
  });
  std::string s;
  for (const auto& d : sorted) {
    if (!s.empty()) s += '\n';
    s += d.str();
  }
  return s;
}

void Diagnostics::throw_if_any() const {
  if (all_.empty()) return;
  const std::string head = all_.size() == 1 ? std::string() : fmt::format("{} errors:\n", all_.size());
  throw InputError(head + text());
}

YAML::Node parse_yaml(std::string_view text, Diagnostics& d) {
  try {
    return YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    d.error(TextMark::of(e.mark), fmt::format("not valid YAML: {}", e.msg));
    return YAML::Node();
  }
}

YAML::Node parse_yaml_map(std::string_view text, Diagnostics& d, const std::string& expected) {
  const size_t before = d.size();
  YAML::Node root = parse_yaml(text, d);
  if (d.size() != before) return YAML::Node();
  if (!root.IsMap()) {
    d.error(root, fmt::format("{}, got {}", expected, describe_node(root)));
    return YAML::Node();
  }
  return root;
}

std::string describe_node(const YAML::Node& n) {
  if (!n.IsDefined() || n.IsNull()) return "nothing";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a map";
  if (n.Tag() == "!") return fmt::format("the quoted text \"{}\"", n.Scalar());
  return fmt::format("\"{}\"", n.Scalar());
}

MapReader::MapReader(const YAML::Node& map, std::string where, Diagnostics& d)
    : map_(map), where_(std::move(where)), d_(d) {
  if (map_.IsDefined() && !map_.IsNull() && !map_.IsMap()) {
    d_.error(map_, fmt::format("{}: expected a map of fields, got {}", where_, describe_node(map_)));
    ok_ = false;
  }
}

bool MapReader::has(const std::string& key) const {
  return ok_ && map_.IsMap() && map_[key].IsDefined();
}

YAML::Node MapReader::node(const std::string& key) {
  known_.insert(key);
  if (!ok_ || !map_.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
  return map_[key];
}

void MapReader::missing(const std::string& what) {
  d_.error(map_, fmt::format("{}: missing field {}", where_, what));
}

YAML::Node MapReader::field(const std::string& key, bool required) {
  YAML::Node n = node(key);
  if (!n.IsDefined() && required && ok_) missing(key);
  return n;
}

NumberRange number_range(std::string_view key) {
  auto ends = [&](std::string_view suffix) {
    return key.size() >= suffix.size() && key.substr(key.size() - suffix.size()) == suffix;
  };
  // Longest suffixes first: "_arcsec_s" before "_s", "_deg_s" before "_s".
  if (ends("_arcsec_s2")) return {-3.6e7, 3.6e7};        // 10,000 deg/s^2
  if (ends("_arcsec_s")) return {-360000, 360000};       // 100 deg/s
  if (ends("_deg_s")) return {-100, 100};
  if (ends("_arcsec")) return {-648000, 648000};         // half a turn
  if (ends("_deg")) return {-180, 180};
  if (ends("_hz")) return {-10000, 10000};
  if (ends("_c")) return {-273.15, 1000};                // degrees Celsius: absolute zero up
  if (ends("_s")) return {-86400, 86400};                // a day: durations, settling, timeouts, offsets
  if (key == "time_scale") return {-10000, 10000};
  return {-1e9, 1e9};
}

std::optional<double> MapReader::as_number(const YAML::Node& n, const std::string& what, Diagnostics& d,
                                           std::string_view key) {
  // A quoted "5" is text: numbers are written plain, so a typo'd quote is caught rather than guessed.
  if (n.IsScalar() && n.Tag() != "!") {
    try {
      const double v = n.as<double>();
      if (std::isfinite(v)) {
        const NumberRange r = number_range(key);
        if (v < r.lo || v > r.hi) {
          d.error(n, fmt::format("{}: {} is outside [{}, {}] (docs/procedures.md, Limits)", what, n.Scalar(), r.lo, r.hi));
          return std::nullopt;
        }
        return v;
      }
    } catch (const YAML::Exception&) {
    }
  }
  d.error(n, fmt::format("{}: expected a number, got {}", what, describe_node(n)));
  return std::nullopt;
}

std::optional<double> MapReader::number(const std::string& key, bool required) {
  YAML::Node n = field(key, required);
  if (!n.IsDefined()) return std::nullopt;
  return as_number(n, fmt::format("{}: field {}", where_, key), d_, key);
}

std::optional<double> MapReader::positive(const std::string& key, bool required) {
  auto v = number(key, required);
  if (v && !(*v > 0)) {
    d_.error(map_[key], fmt::format("{}: field {}: expected a number > 0, got {}", where_, key, *v));
    return std::nullopt;
  }
  return v;
}

std::optional<double> MapReader::non_negative(const std::string& key, bool required) {
  auto v = number(key, required);
  if (v && *v < 0) {
    d_.error(map_[key], fmt::format("{}: field {}: expected a number >= 0, got {}", where_, key, *v));
    return std::nullopt;
  }
  return v;
}

std::optional<int64_t> MapReader::integer(const std::string& key, bool required, int64_t min, int64_t max) {
  YAML::Node n = field(key, required);
  if (!n.IsDefined()) return std::nullopt;
  if (n.IsScalar() && n.Tag() != "!") {
    try {
      const auto v = n.as<int64_t>();
      if (v < min || v > max) {
        d_.error(n, max == INT64_MAX
                        ? fmt::format("{}: field {}: expected an integer >= {}, got {}", where_, key, min, v)
                        : fmt::format("{}: field {}: expected an integer in {}..{}, got {}", where_, key, min,
                                      max, v));
        return std::nullopt;
      }
      return v;
    } catch (const YAML::Exception&) {
    }
  }
  d_.error(n, fmt::format("{}: field {}: expected an integer, got {}", where_, key, describe_node(n)));
  return std::nullopt;
}

std::optional<bool> MapReader::boolean(const std::string& key, bool required) {
  YAML::Node n = field(key, required);
  if (!n.IsDefined()) return std::nullopt;
  if (n.IsScalar() && n.Tag() != "!") {
    try {
      return n.as<bool>();
    } catch (const YAML::Exception&) {
    }
  }
  d_.error(n, fmt::format("{}: field {}: expected true or false, got {}", where_, key, describe_node(n)));
  return std::nullopt;
}

std::optional<std::string> MapReader::string(const std::string& key, bool required) {
  YAML::Node n = field(key, required);
  if (!n.IsDefined()) return std::nullopt;
  if (!n.IsScalar()) {
    d_.error(n, fmt::format("{}: field {}: expected text, got {}", where_, key, describe_node(n)));
    return std::nullopt;
  }
  return n.Scalar();
}

std::optional<std::string> MapReader::choice(const std::string& key, std::initializer_list<std::string_view> options,
                                             bool required) {
  auto s = string(key, required);
  if (!s) return s;
  for (auto o : options) if (*s == o) return s;
  std::string list;
  for (auto o : options) list += (list.empty() ? "" : ", ") + std::string(o);
  d_.error(map_[key], fmt::format("{}: field {}: expected one of {}, got \"{}\"", where_, key, list, *s));
  return std::nullopt;
}

std::optional<std::pair<std::string, double>> MapReader::pick_unit(
    const std::string& base, std::initializer_list<std::pair<const char*, double>> units, bool required) {
  std::vector<std::pair<std::string, double>> given;
  std::string names;
  for (auto [suffix, factor] : units) {
    const std::string key = base + suffix;
    names += (names.empty() ? "" : " or ") + key;
    known_.insert(key);
    if (has(key)) given.emplace_back(key, factor);
  }
  if (given.size() > 1) {
    d_.error(map_[given[1].first], fmt::format("{}: give {} only once (as {} or {}, not both)", where_, base,
                                               given[0].first, given[1].first));
    return std::nullopt;
  }
  if (given.empty()) {
    if (required && ok_) missing(names);
    return std::nullopt;
  }
  return given.front();
}

std::optional<double> MapReader::angle_arcsec(const std::string& base, bool required) {
  auto k = pick_unit(base, {{"_deg", 3600.0}, {"_arcsec", 1.0}}, required);
  if (!k) return std::nullopt;
  const auto v = number(k->first);
  return v ? std::optional(*v * k->second) : std::nullopt;
}

std::optional<double> MapReader::rate_arcsec_s(const std::string& base, bool required) {
  auto k = pick_unit(base, {{"_arcsec_s", 1.0}, {"_deg_s", 3600.0}}, required);
  if (!k) return std::nullopt;
  const auto v = positive(k->first);
  return v ? std::optional(*v * k->second) : std::nullopt;
}

std::optional<std::pair<double, double>> MapReader::angle_range_arcsec(const std::string& base, bool required) {
  auto k = pick_unit(base, {{"_deg", 3600.0}, {"_arcsec", 1.0}}, required);
  if (!k) return std::nullopt;
  auto r = range(k->first);
  if (!r) return std::nullopt;
  return std::pair{r->first * k->second, r->second * k->second};
}

std::optional<std::pair<double, double>> MapReader::range(const std::string& key, bool required) {
  YAML::Node n = field(key, required);
  if (!n.IsDefined()) return std::nullopt;
  const std::string what = fmt::format("{}: field {}", where_, key);
  if (!n.IsSequence() || n.size() != 2) {
    d_.error(n, fmt::format("{}: expected [min, max], got {}", what, describe_node(n)));
    return std::nullopt;
  }
  auto lo = as_number(n[0], what, d_, key);
  auto hi = as_number(n[1], what, d_, key);
  if (!lo || !hi) return std::nullopt;
  if (!(*lo < *hi)) {
    d_.error(n, fmt::format("{}: expected min < max, got [{}, {}]", what, *lo, *hi));
    return std::nullopt;
  }
  return std::pair{*lo, *hi};
}

void MapReader::finish() {
  if (!ok_ || !map_.IsMap()) return;
  std::string known;
  for (const auto& k : known_) known += (known.empty() ? "" : ", ") + k;
  for (auto it = map_.begin(); it != map_.end(); ++it) {
    const std::string key = it->first.IsScalar() ? it->first.Scalar() : std::string();
    if (known_.count(key)) continue;
    d_.error(it->first, fmt::format("{}: unknown field \"{}\" (known: {})", where_, key, known));
  }
}

}  // namespace fpss
