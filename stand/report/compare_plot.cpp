#include "stand/report/compare_plot.h"

#include <fmt/format.h>

#include "base/text_file.h"
#include "calib/units.h"
#include "stand/report/plot.h"

namespace fpss {

namespace fs = std::filesystem;

std::string comparison_plot_data(const CalibrationComparison& c) {
  std::string s = "# angle_a_deg diff_arcsec counts\n";
  for (const AxisComparison* a : {&c.alpha, &c.beta}) {
    s += fmt::format("# {}\n", a->axis);
    for (size_t i = 0; i < a->counts.size(); ++i) {
      s += fmt::format("{:.6f} {:.6f} {:.0f}\n", a->angle_a_arcsec[i] / kArcsecPerDeg, a->diff_arcsec[i], a->counts[i]);
    }
    s += "\n\n";  // gnuplot data block separator (index 0: alpha, 1: beta)
  }
  return s;
}

std::string comparison_plot_script(const CalibrationComparison& c, const std::string& data_path,
                                   const std::string& svg_path, const std::string& title) {
  // Single-quoted: gnuplot substitutes no backquote and interprets no escape inside them.
  auto quote = [](const std::string& text) { return fmt::format("'{}'", gnuplot_quote(text)); };
  std::string s;
  s += "set terminal svg size 900,520 dynamic enhanced font 'sans,12' background rgb 'white'\n";
  s += fmt::format("set output {}\n", quote(svg_path));
  s += fmt::format("set title {} noenhanced\n", quote(title));
  s += fmt::format("set xlabel {}\n", quote(fmt::format("angle under A (deg), +-{} deg", c.range_deg)));
  s += "set ylabel 'B - A (arcsec)'\n";
  s += "set grid\nset key outside right top\n";
  s += fmt::format("plot {} index 0 using 1:2 with lines lw 2 title 'alpha', \\\n", quote(data_path));
  s += fmt::format("     {} index 1 using 1:2 with lines lw 2 title 'beta'\n", quote(data_path));
  return s;
}

void write_comparison_plot(const CalibrationComparison& c, const fs::path& svg, const std::string& title) {
  if (svg.has_parent_path()) fs::create_directories(svg.parent_path());
  fs::path data = svg, script = svg;
  data.replace_extension(".dat");
  script.replace_extension(".gp");
  write_text_atomic(data, comparison_plot_data(c));
  write_text_atomic(script, comparison_plot_script(c, data.string(), svg.string(), title));
  const GnuplotRun run = Gnuplot().run_file(script);
  if (!run.ok()) {
    throw std::runtime_error(
        fmt::format("{}; the data and script are at {} and {}", run.error, data.string(), script.string()));
  }
}

}  // namespace fpss
