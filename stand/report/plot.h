// Plots for HTML reports: gnuplot (svg terminal) run as a child process, its SVG made safe to inline.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace fpss {

// What one gnuplot run gave: the SVG, or why there is none.
struct PlotResult {
  std::optional<std::string> svg;  // ready to inline: no XML prolog, ids prefixed
  std::string error;               // when svg is empty: gnuplot missing, failed (its stderr), ...
  bool program_missing = false;    // gnuplot could not be started at all
};

// How one run of a gnuplot script went.
struct GnuplotRun {
  std::string error;             // empty: it ran and exited 0
  bool program_missing = false;  // gnuplot could not be started at all
  bool ok() const { return error.empty(); }
};

class Gnuplot {
 public:
  // `program`: a name looked up on PATH or a path. Empty: $FPSS_GNUPLOT, else "gnuplot".
  explicit Gnuplot(std::string program = {});

  const std::string& program() const { return program_; }

  // Runs `script` (which must not set a terminal or output: this does) and returns the SVG.
  // Data go in the script as datablocks (see datablock()), so no file is shared with gnuplot.
  // Never throws for gnuplot's own failures: they come back in PlotResult::error.
  PlotResult svg(const std::string& script, const std::string& id_prefix, int width_px = 720,
                 int height_px = 440) const;
  // Runs a script file that sets its own terminal and output, with an argv (no shell), standard
  // output to `stdout_to` (default: discarded); the error holds gnuplot's last stderr lines.
  GnuplotRun run_file(const std::filesystem::path& script, const std::filesystem::path& stdout_to = "/dev/null") const;

 private:
  std::string program_;
};

// A gnuplot datablock `$name << EOD ... EOD` of rows of numbers (NaN written as NaN).
std::string datablock(const std::string& name, const std::vector<std::vector<double>>& rows);

// A text safe inside a gnuplot single-quoted string.
std::string gnuplot_quote(const std::string& text);

// Strips the XML prolog and prefixes every id (and every reference to one) with `prefix`, so
// several SVGs from gnuplot can live in one HTML page without their ids colliding.
std::string inline_svg(const std::string& svg, const std::string& prefix);

}  // namespace fpss
