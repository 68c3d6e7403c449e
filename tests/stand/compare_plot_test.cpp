// The paper's Figures 1-2 as a gnuplot plot, and text that must never reach a shell through it.
#include <gtest/gtest.h>

#include "calib/coefficients.h"
#include "stand/report/compare_plot.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

TEST(Compare, PlotInputsCarryBothAxes) {
  const CalibrationComparison c = compare_calibrations(load_published("a-6-fpss1"), load_published("a-7-fpss1"));
  const std::string data = comparison_plot_data(c);
  EXPECT_NE(data.find("# alpha"), std::string::npos);
  EXPECT_NE(data.find("# beta"), std::string::npos);
  EXPECT_LE(c.alpha.counts.size(), 2001u);
  EXPECT_EQ(c.alpha.counts.back(), static_cast<double>(c.alpha.hi_counts));
  const std::string script = comparison_plot_script(c, "d.dat", "p.svg", "V -> VI");
  EXPECT_NE(script.find("set output 'p.svg'"), std::string::npos);
  EXPECT_NE(script.find("index 1"), std::string::npos);
}

TEST(ComparePlot, BackquotesAndDollarsInLabelsAndPathsRunNothing) {
  test::TempDir tmp("compare-plot");
  const CalibrationComparison c = compare_calibrations(load_published("a-6-fpss1"), load_published("a-7-fpss1"));
  const auto marker1 = tmp / "X1", marker2 = tmp / "X2", marker3 = tmp / "X3";
  const std::string title = "VI `touch " + marker1.string() + "` $(touch " + marker2.string() + ") ' quote";
  const auto svg = tmp / ("plot `touch " + marker3.string() + "`.svg");
  bool have_gnuplot = true;
  try {
    write_comparison_plot(c, svg, title);
  } catch (const std::runtime_error& e) {
    have_gnuplot = std::string(e.what()).find("cannot run gnuplot") == std::string::npos;
    ADD_FAILURE() << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(marker1));
  EXPECT_FALSE(std::filesystem::exists(marker2));
  EXPECT_FALSE(std::filesystem::exists(marker3));
  if (have_gnuplot) {
    EXPECT_TRUE(std::filesystem::exists(svg)) << "the plot is drawn at the path as given";
  }
}

}  // namespace
}  // namespace fpss
