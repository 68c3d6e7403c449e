// INVESTIGATION.html: an investigation's steps (why each run, what it separated) and its final verdict.
#pragma once
#include <filesystem>

#include <nlohmann/json.hpp>

namespace fpss {

// From INVESTIGATION.json's content (stand/investigate/investigation.h); written atomically.
void write_investigation_page(const std::filesystem::path& html_path, const nlohmann::ordered_json& investigation);

}  // namespace fpss
