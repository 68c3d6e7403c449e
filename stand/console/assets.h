// The web console's pages, scripts and styles, built into the binary from stand/console/web/ (embed.cmake).
#pragma once
#include <string_view>
#include <vector>

namespace fpss::console {

struct Asset {
  std::string_view path;  // "/index.html", "/vendor/uPlot.iife.min.js"
  std::string_view body;
};
const std::vector<Asset>& assets();

}  // namespace fpss::console
