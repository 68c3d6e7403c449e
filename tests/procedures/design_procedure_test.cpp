// Designed procedures: offsets listed one by one in a null_offset_grid, and the procedure file
// `fpss-stand design` writes from an experiment design, read back and expanded.
#include <gtest/gtest.h>

#include <vector>

#include "calib/coefficients.h"
#include "calib/design.h"
#include "procedures/design_procedure.h"
#include "procedures/plan.h"
#include "procedures/procedure.h"
#include "tests/procedures/diag_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

using test::has_exactly;

// The offset points of a plan, in recording order, as (pitch, yaw) arcsec; checks that every
// offset lies between two nulls.
std::vector<std::pair<double, double>> offsets_of(const std::string& text, int* frames = nullptr) {
  Diagnostics d("p.yaml");
  const Procedure p = parse_procedure(text, "p.yaml", d);
  EXPECT_TRUE(d.empty()) << d.text();
  const Plan plan = expand(p, EngineSettings{}, d);
  EXPECT_TRUE(d.empty()) << d.text();
  std::vector<std::pair<double, double>> out;
  std::vector<const Action*> pts;
  for (const auto& a : plan.actions) if (a.is_point()) pts.push_back(&a);
  for (size_t i = 0; i < pts.size(); ++i) {
    EXPECT_EQ(pts[i]->phase, i % 2 ? Phase::offset : Phase::null) << i;
    if (i % 2) out.emplace_back(pts[i]->pitch_arcsec, pts[i]->yaw_arcsec);
    if (frames) *frames = pts[i]->frames;
  }
  EXPECT_EQ(pts.size(), 2 * out.size() + 1);
  return out;
}

TEST(DesignedGrid, ListedOffsetsAreMeasuredInTheirOrderBetweenNulls) {
  const auto o = offsets_of(
      "steps:\n  - null_offset_grid:\n      pitch_offsets_deg: [0.1, -0.25]\n"
      "      yaw_offsets_arcsec: [-36, 720.5]\n      frames: 7\n");
  const std::vector<std::pair<double, double>> expected{{360, 0}, {-900, 0}, {0, -36}, {0, 720.5}};
  ASSERT_EQ(o.size(), expected.size());
  for (size_t i = 0; i < o.size(); ++i) {
    EXPECT_NEAR(o[i].first, expected[i].first, 1e-9);
    EXPECT_NEAR(o[i].second, expected[i].second, 1e-9);
  }
  // One axis alone is a grid along that axis only.
  EXPECT_EQ(offsets_of("steps:\n  - null_offset_grid: {yaw_offsets_deg: [0.2], frames: 3}\n").size(), 1u);
}

TEST(DesignedGrid, ListedOffsetsAreCheckedWithTheirPlace) {
  const auto file = test::annotated_file(test::source_dir() / "tests" / "procedures" / "expected_errors" /
                                         "listed_offsets.yaml");
  Diagnostics d(file.name);
  parse_procedure(file.text, file.name, d);
  EXPECT_TRUE(has_exactly(d, file.errors));
}

TEST(DesignedGrid, TheWrittenProcedureIsTheDesign) {
  DesignInputs in;
  in.prior = load_published("a-6-fpss1");
  in.target_sigma_arcsec = 0.03;
  in.extent_deg = 0.42;
  in.frame_rate_hz = 50;
  const ExperimentDesign d = design_experiment(in);
  ASSERT_TRUE(d.reached) << d.note;
  int frames = 0;
  const auto o = offsets_of(design_procedure_text(d, in, "designed: \"x\"\nsteps: []"), &frames);
  ASSERT_EQ(o.size(), d.offsets.size());
  for (size_t i = 0; i < o.size(); ++i) {
    const double want = d.offsets[i].angle_deg * 3600;
    // Written to 0.1 mdeg (0.36 arcsec): the gimbal and the design's candidate step are coarser.
    EXPECT_NEAR(d.offsets[i].pitch ? o[i].first : o[i].second, want, 0.2) << i;
    EXPECT_EQ(d.offsets[i].pitch ? o[i].second : o[i].first, 0.0) << i;
  }
  EXPECT_EQ(frames, d.samples_per_dwell);
}

}  // namespace
}  // namespace fpss
