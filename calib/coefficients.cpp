#include "calib/coefficients.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "base/errors.h"
#include "base/json_file.h"
#include "base/text_file.h"

namespace fpss {
namespace {

AxisCoeffs parse_axis(const nlohmann::json& j, const char* key, const std::string& origin) {
  if (!j.contains(key)) {
    throw InputError(fmt::format("{}: missing key \"{}\" (expected an array of 8 finite numbers C1..C8)",
                                 origin, key));
  }
  const auto& a = j.at(key);
  if (!a.is_array() || a.size() != 8) {
    throw InputError(fmt::format("{}: key \"{}\" must be an array of 8 numbers C1..C8, got {}",
                                 origin, key, a.dump()));
  }
  AxisCoeffs c{};
  for (size_t i = 0; i < 8; ++i) {
    if (!a[i].is_number() || !std::isfinite(a[i].get<double>())) {
      throw InputError(fmt::format("{}: \"{}\"[{}] (C{}) must be a finite number, got {}", origin,
                                   key, i, i + 1, a[i].dump()));
    }
    if (std::abs(a[i].get<double>()) > kMaxAbsCoefficient) {
      throw InputError(fmt::format("{}: \"{}\"[{}] (C{}) = {} is beyond +-{:g} (docs/formats.md, Limits)", origin, key,
                                   i, i + 1, a[i].dump(), kMaxAbsCoefficient));
    }
    c[i] = a[i].get<double>();
  }
  return c;
}

}  // namespace

CoefficientSet parse_coefficients(const nlohmann::json& j, const std::string& origin) {
  if (!j.is_object()) throw InputError(fmt::format("{}: expected a JSON object", origin));
  CoefficientSet s;
  if (j.contains("unit")) {
    if (!j["unit"].is_string()) throw InputError(fmt::format("{}: \"unit\" must be a string", origin));
    s.unit = j["unit"].get<std::string>();
  }
  s.alpha = parse_axis(j, "alpha", origin);
  s.beta = parse_axis(j, "beta", origin);
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (it.key() != "unit" && it.key() != "alpha" && it.key() != "beta") s.extra[it.key()] = it.value();
  }
  return s;
}

CoefficientSet load_coefficients(const std::filesystem::path& path) {
  return parse_coefficients(read_json_file(path, "coefficient file"), path.string());
}

nlohmann::json to_json(const CoefficientSet& s) {
  nlohmann::json j = nlohmann::json::object();
  j["unit"] = s.unit;
  j["alpha"] = s.alpha;
  j["beta"] = s.beta;
  for (auto it = s.extra.begin(); it != s.extra.end(); ++it) j[it.key()] = it.value();
  return j;
}

void save_coefficients(const std::filesystem::path& path, const CoefficientSet& s) {
  write_text_atomic(path, to_json(s).dump(1) + "\n");
}

std::filesystem::path published_dir() {
  if (const char* d = std::getenv("FPSS_DATA_DIR")) return std::filesystem::path(d) / "published";
  return std::filesystem::path(FPSS_SOURCE_DIR) / "calib" / "data" / "published";
}

std::vector<std::string> published_names() {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(published_dir())) {
    if (e.path().extension() == ".json") names.push_back(e.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

CoefficientSet load_published(const std::string& name) {
  const auto p = published_dir() / (name + ".json");
  if (!std::filesystem::exists(p)) {
    throw InputError(fmt::format("no published coefficient set \"{}\" (looked for {})", name, p.string()));
  }
  return load_coefficients(p);
}

bool is_suspect(const CoefficientSet& s) { return s.extra.contains("suspect"); }

}  // namespace fpss
