// Procedure files: parsing, validation with every error at file:line:column, expansion and the dry-run text.
#include <gtest/gtest.h>

#include <cmath>
#include <regex>
#include <set>

#include "base/errors.h"
#include "procedures/plan.h"
#include "procedures/procedure.h"
#include "tests/procedures/diag_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

using test::has_error;
using test::has_exactly;
using test::TempDir;

Procedure parse_ok(const std::string& text, const std::string& origin = "p.yaml") {
  Diagnostics d(origin);
  Procedure p = parse_procedure(text, origin, d);
  EXPECT_TRUE(d.empty()) << d.text();
  return p;
}

Diagnostics parse_bad(const std::string& text, const std::string& origin = "bad.yaml") {
  Diagnostics d(origin);
  parse_procedure(text, origin, d);
  return d;
}

EngineSettings bench() {
  EngineSettings b;
  b.sample_rate_hz = 50;
  return b;
}

TEST(Procedure, ShippedProceduresParseAndExpand) {
  for (const char* name : {"discrete_grid", "full_grid", "continuous_slew"}) {
    const auto path = test::source_dir() / "procedures" / (std::string(name) + ".yaml");
    Procedure p = load_procedure(path);
    EXPECT_EQ(p.name, name);
    EXPECT_FALSE(p.description.empty());
    Diagnostics d(path.string());
    Plan plan = expand(p, bench(), d);
    EXPECT_TRUE(d.empty()) << d.text();
    EXPECT_GT(plan.points, 0u);
    EXPECT_GT(plan.estimated_s, 0.0);
  }
}

TEST(Procedure, DiscreteGridIsThePapersPattern) {
  Procedure p = load_procedure(test::source_dir() / "procedures" / "discrete_grid.yaml");
  Diagnostics d("discrete_grid.yaml");
  Plan plan = expand(p, bench(), d);
  ASSERT_TRUE(d.empty()) << d.text();
  std::vector<const Action*> pts;
  for (const auto& a : plan.actions) if (a.is_point()) pts.push_back(&a);
  ASSERT_EQ(pts.size(), plan.points);
  // null, offset, null, offset, ..., null: every offset between two nulls.
  ASSERT_EQ(pts.size() % 2, 1u);
  std::set<double> pitch_offsets, yaw_offsets;
  for (size_t i = 0; i < pts.size(); ++i) {
    EXPECT_EQ(pts[i]->point, static_cast<int64_t>(i));
    if (i % 2 == 0) {
      EXPECT_EQ(pts[i]->phase, Phase::null);
      EXPECT_EQ(pts[i]->pitch_arcsec, 0.0);
      EXPECT_EQ(pts[i]->yaw_arcsec, 0.0);
    } else {
      EXPECT_EQ(pts[i]->phase, Phase::offset);
      EXPECT_TRUE(pts[i]->pitch_arcsec == 0.0 || pts[i]->yaw_arcsec == 0.0);
      if (pts[i]->yaw_arcsec == 0.0) pitch_offsets.insert(pts[i]->pitch_arcsec);
      else yaw_offsets.insert(pts[i]->yaw_arcsec);
    }
    EXPECT_EQ(pts[i]->frames, 10);
  }
  // +-0.42 deg in 0.03 deg steps on both axes.
  EXPECT_EQ(pitch_offsets.size(), 28u);
  EXPECT_EQ(yaw_offsets.size(), 28u);
  EXPECT_NEAR(*pitch_offsets.rbegin(), 0.42 * 3600, 1e-6);
  EXPECT_NEAR(*pitch_offsets.begin(), -0.42 * 3600, 1e-6);
  EXPECT_NEAR(*yaw_offsets.rbegin(), 0.42 * 3600, 1e-6);
  // Outward order: +step, -step, +2 step, ...
  EXPECT_NEAR(pts[1]->pitch_arcsec, 108, 1e-9);
  EXPECT_NEAR(pts[3]->pitch_arcsec, -108, 1e-9);
  EXPECT_NEAR(pts[5]->pitch_arcsec, 216, 1e-9);
  // The plan ends with calibrate and check.
  EXPECT_EQ(plan.actions[plan.actions.size() - 2].kind, Action::Kind::calibrate);
  EXPECT_EQ(plan.actions.back().kind, Action::Kind::check);
}

TEST(Procedure, FullGridCoversTheFieldWithDiagonals) {
  Procedure p = load_procedure(test::source_dir() / "procedures" / "full_grid.yaml");
  Diagnostics d("full_grid.yaml");
  Plan plan = expand(p, bench(), d);
  ASSERT_TRUE(d.empty()) << d.text();
  std::set<std::pair<double, double>> offsets;
  for (const auto& a : plan.actions) {
    if (a.kind == Action::Kind::dwell && a.phase == Phase::offset) offsets.insert({a.pitch_arcsec, a.yaw_arcsec});
  }
  EXPECT_EQ(offsets.size(), 80u);  // 9 x 9 lattice without the centre
  const double e = 0.42 * 3600;
  for (auto c : {std::pair{e, e}, std::pair{-e, e}, std::pair{e, -e}, std::pair{-e, -e}}) {
    EXPECT_EQ(offsets.count(c), 1u) << c.first << "," << c.second;
  }
  EXPECT_EQ(plan.points, 161u);
}

TEST(Procedure, SlewSegmentsBothRatesBothDirections) {
  Procedure p = load_procedure(test::source_dir() / "procedures" / "continuous_slew.yaml");
  Diagnostics d("continuous_slew.yaml");
  Plan plan = expand(p, bench(), d);
  ASSERT_TRUE(d.empty()) << d.text();
  std::set<std::tuple<int, double, double>> segs;  // axis, rate, direction
  for (const auto& a : plan.actions) {
    if (a.kind != Action::Kind::slew) continue;
    const double from = a.axis == StandAxis::pitch ? a.start_pitch_arcsec : a.start_yaw_arcsec;
    const double to = a.axis == StandAxis::pitch ? a.pitch_arcsec : a.yaw_arcsec;
    EXPECT_NEAR(std::fabs(from), 0.42 * 3600, 1e-6);
    EXPECT_NEAR(to, -from, 1e-9);
    EXPECT_EQ(a.phase, Phase::slew);
    segs.insert({static_cast<int>(a.axis), a.rate_arcsec_s, to > from ? 1.0 : -1.0});
  }
  EXPECT_EQ(segs.size(), 8u);
}

// A slew that reverses inside one segment: one point whose legs alternate far end / start, the
// estimate counting every leg; a reversal count out of range is an error at the field.
TEST(Procedure, SlewReversalsStayInOneSegment) {
  auto plan_of = [](const std::string& text, Diagnostics& d) {
    Procedure p = parse_procedure(text, "r.yaml", d);
    return expand(p, bench(), d);
  };
  const std::string base =
      "steps:\n  - continuous_slew: {axis: yaw, amplitude_arcsec: 900, rate_arcsec_s: 300, sample_period_s: 0.1, "
      "directions: positive";
  Diagnostics d0("r.yaml"), d2("r.yaml");
  const Plan one_way = plan_of(base + "}\n", d0);
  const Plan there_and_back = plan_of(base + ", reversals: 2}\n", d2);
  ASSERT_TRUE(d0.empty() && d2.empty()) << d0.text() << d2.text();
  ASSERT_EQ(there_and_back.points, 1u);
  const Action& a = there_and_back.actions[there_and_back.point_action[0]];
  EXPECT_EQ(a.reversals, 2);
  EXPECT_DOUBLE_EQ(a.start_yaw_arcsec, -900);
  EXPECT_DOUBLE_EQ(a.yaw_arcsec, 900);         // the far end
  EXPECT_DOUBLE_EQ(a.end_yaw_arcsec(), 900);   // even: ends at the far end
  EXPECT_GT(there_and_back.estimated_s, one_way.estimated_s + 2 * 1800 / 300.0 - 1e-9);  // two more legs
  EXPECT_NE(a.describe().find("and back (2 reversals)"), std::string::npos) << a.describe();
  Diagnostics bad("r.yaml");
  plan_of(base + ", reversals: 21}\n", bad);
  EXPECT_NE(bad.text().find("reversals"), std::string::npos) << bad.text();
}

TEST(Procedure, EveryErrorAtOnceWithLineAndColumn) {
  const auto file = test::annotated_file(test::source_dir() / "tests" / "procedures" / "expected_errors" /
                                         "every_error.yaml");
  Diagnostics d = parse_bad(file.text, file.name);
  EXPECT_TRUE(has_exactly(d, file.errors));
  // The text names the file for each.
  EXPECT_NE(d.text().find("every_error.yaml:5:5: step 2: unknown step \"jump\""), std::string::npos) << d.text();
}

TEST(Procedure, LoadThrowsInputErrorListingAll) {
  TempDir tmp("procedure");
  const auto f = tmp / "two_errors.yaml";
  test::write_file(f, "steps:\n  - settle: {duration_s: -1}\n  - moove: {}\n");
  try {
    load_procedure(f);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("2 errors"), std::string::npos) << m;
    EXPECT_NE(m.find(f.string() + ":2:26: step 1 (settle): field duration_s: expected a number > 0"), std::string::npos)
        << m;
    EXPECT_NE(m.find(f.string() + ":3:5: step 2: unknown step \"moove\""), std::string::npos) << m;
  }
}

TEST(Procedure, SyntaxErrorHasAPlace) {
  Diagnostics d = parse_bad("steps:\n  - home\n  - move: {pitch_deg: 1\n");
  ASSERT_EQ(d.size(), 1u);
  EXPECT_GT(d.all()[0].mark.line, 0);
  EXPECT_NE(d.all()[0].message.find("not valid YAML"), std::string::npos);
}

TEST(Procedure, StructuralErrors) {
  EXPECT_TRUE(has_error(parse_bad("steps: []\n"), 1, 8, "non-empty list"));
  EXPECT_TRUE(has_error(parse_bad("name: x\n"), 1, 1, "missing field steps"));
  EXPECT_TRUE(has_error(parse_bad("steps:\n  - home\nextra: 1\n"), 3, 1, "unknown field \"extra\""));
  // A step written with two keys is ambiguous.
  EXPECT_TRUE(has_error(parse_bad("steps:\n  - home: {}\n    settle: {duration_s: 1}\n"), 2, 5, "a map with 2 keys"));
  // Quoted numbers are text, not numbers.
  EXPECT_TRUE(has_error(parse_bad("steps:\n  - settle: {duration_s: \"2\"}\n"), 2, 26, "quoted text"));
  // frames and duration together, degrees and arcsec together.
  EXPECT_FALSE(parse_bad("steps:\n  - sample: {frames: 3, duration_s: 1}\n").empty());
  EXPECT_FALSE(parse_bad("steps:\n  - move: {pitch_deg: 0.1, pitch_arcsec: 360}\n").empty());
  // A check needs a calibration before it.
  EXPECT_TRUE(has_error(parse_bad("steps:\n  - check: {max_abs_arcsec: 1}\n"), 2, 5, "calibrate step before"));
  // Grid step larger than the extent.
  EXPECT_FALSE(parse_bad("steps:\n  - null_offset_grid: {extent_deg: 0.1, step_deg: 0.2, frames: 2}\n").empty());
  // Integers stay integers.
  EXPECT_TRUE(has_error(parse_bad("steps:\n  - sample: {frames: 2.5}\n"), 2, 22, "expected an integer"));
  // An init file that does not exist is caught before anything moves.
  EXPECT_FALSE(parse_bad("steps:\n  - calibrate: {init: /nonexistent/set.json}\n").empty());
}

TEST(Procedure, UnitsAndDefaults) {
  Procedure p = parse_ok(
      "steps:\n"
      "  - move: {pitch_deg: 0.1, yaw_arcsec: -100, rate_deg_s: 0.25}\n"
      "  - sample: {duration_s: 0.5}\n"
      "  - continuous_slew: {axis: yaw, amplitude_arcsec: 900, rate_deg_s: 0.1, sample_period_s: 0.2}\n");
  const auto& mv = std::get<MoveStep>(p.steps[0].body);
  EXPECT_DOUBLE_EQ(*mv.pitch_arcsec, 360);
  EXPECT_DOUBLE_EQ(*mv.yaw_arcsec, -100);
  EXPECT_DOUBLE_EQ(*mv.rate_arcsec_s, 900);
  const auto& sm = std::get<SampleStep>(p.steps[1].body);
  EXPECT_EQ(sm.frames.count(50), 25);
  const auto& sl = std::get<SlewStep>(p.steps[2].body);
  ASSERT_EQ(sl.rates_arcsec_s.size(), 1u);
  EXPECT_DOUBLE_EQ(sl.rates_arcsec_s[0], 360);
  EXPECT_EQ(sl.directions, SlewStep::Directions::both);

  Diagnostics d("p.yaml");
  Plan plan = expand(p, bench(), d);
  ASSERT_TRUE(d.empty()) << d.text();
  // The sample after the move measures at the moved-to target, phase offset (not at null).
  const Action* sample = nullptr;
  for (const auto& a : plan.actions) if (a.kind == Action::Kind::dwell) sample = &a;
  ASSERT_NE(sample, nullptr);
  EXPECT_DOUBLE_EQ(sample->pitch_arcsec, 360);
  EXPECT_DOUBLE_EQ(sample->yaw_arcsec, -100);
  EXPECT_EQ(sample->phase, Phase::offset);
}

TEST(Procedure, GridOrders) {
  GridStep g;
  g.extent_arcsec = 300;
  g.step_arcsec = 100;
  g.order = GridStep::Order::outward;
  EXPECT_EQ(g.offsets_arcsec(), (std::vector<double>{100, -100, 200, -200, 300, -300}));
  g.order = GridStep::Order::ascending;
  EXPECT_EQ(g.offsets_arcsec(), (std::vector<double>{-300, -200, -100, 100, 200, 300}));
  g.order = GridStep::Order::descending;
  EXPECT_EQ(g.offsets_arcsec(), (std::vector<double>{300, 200, 100, -100, -200, -300}));
  // 0.42 / 0.06 is 7 despite floating point.
  g.extent_arcsec = 0.42 * 3600;
  g.step_arcsec = 0.06 * 3600;
  EXPECT_EQ(g.offsets_arcsec().size(), 14u);
}

TEST(Plan, TargetsOutsideSoftLimitsAreErrorsAtTheStep) {
  Procedure p = parse_ok(
      "steps:\n"
      "  - home\n"
      "  - null_offset_grid: {extent_deg: 0.42, step_deg: 0.14, frames: 2}\n"
      "  - move: {yaw_deg: -0.6}\n"
      "  - continuous_slew: {axis: pitch, amplitude_deg: 0.2, rate_arcsec_s: 5000, sample_period_s: 0.01}\n",
      "limits.yaml");
  EngineSettings b = bench();
  b.limits.pitch_min_arcsec = -0.3 * 3600;
  b.limits.pitch_max_arcsec = 0.3 * 3600;
  b.limits.yaw_min_arcsec = -0.5 * 3600;
  b.limits.yaw_max_arcsec = 0.5 * 3600;
  b.limits.max_rate_arcsec_s = 3600;
  Diagnostics d("limits.yaml");
  expand(p, b, d);
  EXPECT_TRUE(has_exactly(d, {{3, 5, "step 2 (null_offset_grid): target out of soft limits: pitch +0.4200 deg"},
                              {4, 5, "step 3 (move): target out of soft limits: yaw -0.6000 deg"},
                              {5, 5, "rate 5000 arcsec/s is above the soft limit"},
                              {5, 5, "shorter than the sensor's frame period"}}));
}

TEST(Plan, MoveDurationIsTrapezoidal) {
  // Triangle: 900 arcsec at 3600 arcsec/s^2 never reaches 1800 arcsec/s: 2 sqrt(900/3600) = 1 s.
  EXPECT_NEAR(move_duration_s(0, 0, 900, 0, 1800, 3600), 1.0, 1e-12);
  // Trapezoid: 3600 arcsec: 3600/1800 + 1800/3600 = 2.5 s; both axes at once: the longer.
  EXPECT_NEAR(move_duration_s(0, 0, 3600, -900, 1800, 3600), 2.5, 1e-12);
  EXPECT_EQ(move_duration_s(5, 5, 5, 5, 1800, 3600), 0.0);
}

TEST(Plan, EstimateAddsMovesSettlesAndFrames) {
  Procedure p = parse_ok(
      "steps:\n"
      "  - move: {pitch_arcsec: 900}\n"
      "  - settle: {duration_s: 2}\n"
      "  - sample: {frames: 50}\n");
  EngineSettings b = bench();
  b.profile_rate_arcsec_s = 1800;
  b.acceleration_arcsec_s2 = 3600;
  Diagnostics d("p.yaml");
  Plan plan = expand(p, b, d);
  // 1 s out, 2 s settle, 1 s of frames at 50 Hz, 1 s back to null at the end.
  EXPECT_NEAR(plan.estimated_s, 5.0, 1e-9);
  EXPECT_EQ(plan.points, 1u);
  EXPECT_EQ(plan.frames, 50u);
}

TEST(Plan, SamePlanEveryTime) {
  Procedure p = load_procedure(test::source_dir() / "procedures" / "full_grid.yaml");
  Diagnostics d1("a"), d2("b");
  Plan a = expand(p, bench(), d1), b = expand(p, bench(), d2);
  ASSERT_EQ(a.actions.size(), b.actions.size());
  for (size_t i = 0; i < a.actions.size(); ++i) {
    EXPECT_EQ(a.actions[i].point, b.actions[i].point);
    EXPECT_EQ(a.actions[i].pitch_arcsec, b.actions[i].pitch_arcsec);
    EXPECT_EQ(a.actions[i].yaw_arcsec, b.actions[i].yaw_arcsec);
    EXPECT_EQ(a.actions[i].phase, b.actions[i].phase);
  }
}

TEST(Plan, DryRunText) {
  Procedure p = load_procedure(test::source_dir() / "procedures" / "discrete_grid.yaml");
  EngineSettings b = bench();
  b.time_scale = 20;
  Diagnostics d("x");
  Plan plan = expand(p, b, d);
  const std::string s = format_plan(p, plan, b);
  EXPECT_NE(s.find("points: 113 (57 null, 56 offset, 0 slew segments); frames kept: 1130"), std::string::npos) << s;
  EXPECT_NE(s.find("estimated duration:"), std::string::npos);
  EXPECT_NE(s.find("at speed-up 20"), std::string::npos);
  EXPECT_NE(s.find("point  113 null"), std::string::npos) << s;
  EXPECT_NE(s.find("all targets inside the soft limits"), std::string::npos);
}

TEST(Procedure, Sha256) {
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

// A procedure with one grid step whose fields are given as text (one per line, 6 spaces in).
std::string grid_procedure(const std::string& fields) {
  return "name: g\nsteps:\n  - null_offset_grid:\n      axes: [pitch, yaw]\n" + fields;
}

TEST(Procedure, EveryNumberHasARangeNamedWithItsPlace) {
  struct Case {
    std::string fields;
    int line, col;
    std::string says;
  };
  const std::vector<Case> cases = {
      // step_deg: 1e-7 once exhausted memory (4.2 million offsets per axis); 1e-5 still gives 336,001 points.
      {"      extent_deg: 0.42\n      step_deg: 1e-5\n      frames: 1\n", 4, 7, "points; a plan may have at most 100000"},
      // 1e-12 gave a silently empty plan (an overflowing int of offsets).
      {"      extent_deg: 0.42\n      step_deg: 1e-12\n      frames: 1\n", 6, 17, "finer than the gimbal's resolution"},
      {"      extent_deg: 0.42\n      step_deg: 0.03\n      duration_s: 1e308\n", 7, 19,
       "field duration_s: 1e308 is outside [-86400, 86400]"},
      {"      extent_deg: 0.42\n      step_deg: 0.03\n      frames: 1\n      settle_s: 1e308\n", 8, 17,
       "field settle_s: 1e308 is outside"},
      {"      extent_deg: 1e300\n      step_deg: 0.03\n      frames: 1\n", 5, 19, "field extent_deg: 1e300 is outside [-180, 180]"},
      {"      extent_deg: .inf\n      step_deg: 0.03\n      frames: 1\n", 5, 19, "expected a number"},
      {"      extent_deg: 0.42\n      step_deg: 0.03\n      frames: 1\n      layout: full\n      extent_deg: 0.5\n", 0, 0, ""},
  };
  for (const auto& c : cases) {
    if (c.says.empty()) continue;
    SCOPED_TRACE(c.fields);
    const Diagnostics d = parse_bad(grid_procedure(c.fields));
    EXPECT_TRUE(has_error(d, c.line, c.col, c.says)) << d.text();
    EXPECT_NE(d.text().find("bad.yaml:"), std::string::npos);
  }
  // The full layout squares the count: 0.42 deg in steps of 0.001 deg is 841 x 841 lattice points.
  const Diagnostics full = parse_bad(grid_procedure("      extent_deg: 0.42\n      step_deg: 0.001\n      frames: 1\n      layout: full\n"));
  EXPECT_NE(full.text().find("a plan may have at most 100000"), std::string::npos) << full.text();
  // Within the limits, as the shipped procedures are.
  parse_ok(grid_procedure("      extent_deg: 0.42\n      step_deg: 0.01\n      frames: 1\n      settle_s: 3600\n"));
}

TEST(Procedure, PlansAreCappedAtOneHundredThousandPoints) {
  // Each grid alone is within the limit; together they are not.
  std::string text = "name: many\nsteps:\n";
  for (int i = 0; i < 3; ++i) text += "  - null_offset_grid:\n      axes: [pitch, yaw]\n      extent_deg: 0.42\n      step_deg: 0.000035\n      frames: 1\n";
  const Procedure p = parse_ok(text);
  Diagnostics d("many.yaml");
  const Plan plan = expand(p, bench(), d);
  EXPECT_NE(d.text().find("the plan reaches more than 100000 points"), std::string::npos) << d.text();
  EXPECT_LE(plan.points, kMaxPlanPoints);
  // The dry-run estimate stays finite and positive for the largest settling allowed.
  const Procedure slow = parse_ok(grid_procedure("      extent_deg: 0.06\n      step_deg: 0.03\n      frames: 1\n      settle_s: 86400\n"));
  Diagnostics d2("slow.yaml");
  const Plan sp = expand(slow, bench(), d2);
  EXPECT_TRUE(d2.empty()) << d2.text();
  EXPECT_GT(sp.estimated_s, 9 * 86400.0);
  EXPECT_TRUE(std::isfinite(sp.estimated_s));
}

TEST(Procedure, RangesChosenByTheFieldsUnit) {
  EXPECT_EQ(number_range("settle_s").hi, 86400);
  EXPECT_EQ(number_range("max_rate_arcsec_s").hi, 360000);
  EXPECT_EQ(number_range("rate_deg_s").hi, 100);
  EXPECT_EQ(number_range("step_deg").hi, 180);
  EXPECT_EQ(number_range("pitch_arcsec").lo, -648000);
  EXPECT_EQ(number_range("acceleration_arcsec_s2").hi, 3.6e7);
  EXPECT_EQ(number_range("sample_rate_hz").hi, 10000);
  EXPECT_EQ(number_range("anything_else").hi, 1e9);
}

}  // namespace
}  // namespace fpss
