// Coefficient files (JSON): {"unit", "alpha": [C1..C8], "beta": [C1..C8], ...}, read and written with validation.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/transfer_function.h"

namespace fpss {

struct CoefficientSet {
  std::string unit;
  AxisCoeffs alpha{};  // pitch angle from counts_alpha
  AxisCoeffs beta{};   // yaw angle from counts_beta
  nlohmann::json extra = nlohmann::json::object();  // every other key, kept as read

  AxisModel alpha_model() const { return AxisModel(alpha); }
  AxisModel beta_model() const { return AxisModel(beta); }
};

// Largest |C1..C8| taken from a file (radians, rad/count; the paper's are below 4): anything
// beyond is a corrupt file, not a sensor (docs/formats.md, Limits).
inline constexpr double kMaxAbsCoefficient = 1e3;

// Throws InputError naming `origin` (the file) and the key at fault (non-finite, beyond
// kMaxAbsCoefficient). load_coefficients reads with read_json_file (size, depth, duplicate keys).
CoefficientSet parse_coefficients(const nlohmann::json& j, const std::string& origin);
CoefficientSet load_coefficients(const std::filesystem::path& path);
nlohmann::json to_json(const CoefficientSet& set);
// Writes atomically (temporary file, fsync, rename) so a crash never leaves half a file.
void save_coefficients(const std::filesystem::path& path, const CoefficientSet& set);

// The 14 sets of the paper's Tables A-1..A-7 shipped in calib/data/published.
// $FPSS_DATA_DIR overrides the folder (an installed copy).
std::filesystem::path published_dir();
std::vector<std::string> published_names();  // "a-1-fpss1", ... sorted
CoefficientSet load_published(const std::string& name);
// True for the sets whose printed figures look misprinted (docs/formats.md: Table A-7 FPSS1 B7,
// Table A-3 FPSS2 B8, Table A-1 FPSS1 A5 in Gambardella and Thompson, 1980).
bool is_suspect(const CoefficientSet& set);

}  // namespace fpss
