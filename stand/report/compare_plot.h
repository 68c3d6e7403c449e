// The paper's Figures 1-2 as a plot: B - A over the range, both axes (`compare --plot`).
#pragma once
#include <filesystem>
#include <string>

#include "calib/compare.h"

namespace fpss {

// Gnuplot inputs: the data (angle under A in deg, alpha and beta differences in arcsec, one block
// per axis) and a script that draws `svg_path` from `data_path`. Every text (paths, title) goes
// in single quotes, so nothing in it reaches gnuplot's backquote substitution or a shell.
std::string comparison_plot_data(const CalibrationComparison& c);
std::string comparison_plot_script(const CalibrationComparison& c, const std::string& data_path,
                                   const std::string& svg_path, const std::string& title);

// The SVG at `svg`, with its data (.dat) and script (.gp) next to it to redraw it; gnuplot runs
// with an argv. Throws std::runtime_error naming the script when gnuplot fails.
void write_comparison_plot(const CalibrationComparison& c, const std::filesystem::path& svg, const std::string& title);

}  // namespace fpss
