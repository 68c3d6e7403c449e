// A grid's adaptive stop (`until`): the plan's groups and coarse-to-fine order, and the engine
// skipping a group's remaining points once the live fit's sigma (a hook here) reaches the target,
// journalling them so that a resume does not measure them.
#include <gtest/gtest.h>

#include <csignal>
#include <limits>

#include "calib/samples.h"
#include "tests/procedures/engine_fixture.h"

namespace fpss {
namespace {

using test::Bench;
using test::TempDir;
constexpr double kInf = std::numeric_limits<double>::infinity();
const std::string kUntil = ", order: spread, until: {angle_sigma_max_arcsec: 0.05}";

std::vector<const Action*> points_of(const Plan& plan) {
  std::vector<const Action*> out;
  for (size_t i : plan.point_action) out.push_back(&plan.actions[i]);
  return out;
}

TEST(AdaptiveStop, EachAxisIsAGroupTakenCoarseToFine) {
  TempDir tmp("until-plan");
  Bench bench(tmp / "run", kUntil);
  const auto pts = points_of(bench.plan);
  ASSERT_EQ(pts.size(), 33u);  // null + 2 axes x 8 offsets, each followed by a null
  // Offsets of 0.05 deg steps to 0.2 deg: 0.2, 0.1, 0.05, 0.15 (each + then -).
  const std::vector<double> pitch_deg{0.2, -0.2, 0.1, -0.1, 0.05, -0.05, 0.15, -0.15};
  for (size_t k = 0; k < pitch_deg.size(); ++k) {
    EXPECT_NEAR(pts[1 + 2 * k]->pitch_arcsec, pitch_deg[k] * 3600, 1e-6) << k;
    EXPECT_NEAR(pts[17 + 2 * k]->yaw_arcsec, pitch_deg[k] * 3600, 1e-6) << k;
  }
  for (size_t i = 0; i < pts.size(); ++i) {
    EXPECT_DOUBLE_EQ(pts[i]->until_sigma_arcsec, 0.05);
    EXPECT_FALSE(pts[i]->until_both_axes);
    EXPECT_EQ(pts[i]->until_group, i < 17 ? 0 : 1) << i;
    EXPECT_EQ(pts[i]->axis, i < 17 ? StandAxis::pitch : StandAxis::yaw) << i;
  }
  // Without `until` nothing is grouped.
  TempDir tmp2("until-none");
  Bench plain(tmp2 / "run");
  for (const Action* a : points_of(plain.plan)) EXPECT_EQ(a->until_group, -1);
}

TEST(AdaptiveStop, AReachedTargetSkipsTheGroupsRestAndTheRunGoesOn) {
  TempDir tmp("until-run");
  Bench bench(tmp / "run", kUntil);
  int pitch_done = 0;
  std::vector<int64_t> asked;
  bench.on_point_done([&](const PointDone& p) { pitch_done += bench.plan.actions[bench.plan.point_action[p.point.index]].axis == StandAxis::pitch ? 1 : 0; });
  // The pitch fit is good enough after 7 pitch points; yaw never is.
  bench.hooks.until_sigma = [&](const Action& a) {
    asked.push_back(a.point);
    return a.axis == StandAxis::pitch && pitch_done >= 7 ? 0.04 : kInf;
  };
  std::vector<StepStopped> stops;
  bench.bus.subscribe([&](const Event& e) {
    if (const auto* s = std::get_if<StepStopped>(&e)) stops.push_back(*s);
  });
  const auto engine = bench.engine();
  const EngineResult r = engine->run();
  ASSERT_EQ(r.outcome, RunOutcome::completed) << r.reason;
  EXPECT_EQ(r.points_done, 33);
  EXPECT_EQ(engine->stats().points, 7 + 16);
  ASSERT_EQ(stops.size(), 1u);
  EXPECT_EQ(stops[0].axes, "pitch");
  EXPECT_EQ(stops[0].step_index, 2u);
  EXPECT_DOUBLE_EQ(stops[0].sigma_max_arcsec, 0.04);
  ASSERT_EQ(stops[0].skipped.size(), 10u);
  for (size_t k = 0; k < 10; ++k) EXPECT_EQ(stops[0].skipped[k], static_cast<int64_t>(7 + k));
  // Asked before every measured point of both groups and the one that stopped, never after.
  EXPECT_EQ(asked.size(), 7u + 1 + 16);
  // The journal keeps every point in order; the skipped ones have no rows.
  const auto journal = RunRecorder::read_journal(tmp / "run" / "points.jsonl");
  ASSERT_EQ(journal.size(), 33u);
  for (const auto& j : journal) {
    const bool skipped = j.point >= 7 && j.point < 17;
    EXPECT_EQ(j.skipped, skipped ? "until" : "") << j.point;
    EXPECT_EQ(j.rows, skipped ? 0u : 4u) << j.point;
  }
  EXPECT_EQ(read_samples_csv(tmp / "run" / "samples.csv").size(), (7u + 16u) * 4u);
  // The gimbal went on to the yaw offsets from null and is back at null.
  const GimbalState st = bench.gimbal.read_state();
  EXPECT_NEAR(st.pitch_arcsec, 0, 1.0);
  EXPECT_NEAR(st.yaw_arcsec, 0, 1.0);
}

TEST(AdaptiveStop, AResumeAfterAStopDoesNotMeasureTheSkippedPoints) {
  TempDir tmp("until-resume");
  Bench bench(tmp / "run", kUntil);
  bench.hooks.until_sigma = [](const Action& a) { return a.point >= 5 && a.axis == StandAxis::pitch ? 0.01 : kInf; };
  // Interrupt during the yaw group.
  bench.on_point_done([&](const PointDone& p) {
    if (p.point.index == 20) {
      bench.ctl.signal = SIGINT;
      bench.ctl.abort = true;
    }
  });
  const EngineResult r = bench.engine()->run();
  ASSERT_EQ(r.outcome, RunOutcome::interrupted);
  EXPECT_EQ(r.points_done, 21);

  Bench again(tmp / "run", kUntil);
  EXPECT_EQ(again.recorder->next_point(), 21);
  int asked_pitch = 0;
  again.hooks.until_sigma = [&](const Action& a) {
    asked_pitch += a.axis == StandAxis::pitch ? 1 : 0;
    return kInf;
  };
  const auto engine = again.engine(again.recorder->resume_point());
  const EngineResult r2 = engine->run(2);
  ASSERT_EQ(r2.outcome, RunOutcome::completed) << r2.reason;
  EXPECT_EQ(asked_pitch, 0);
  EXPECT_EQ(engine->stats().points, 33 - 21);
  const auto journal = RunRecorder::read_journal(tmp / "run" / "points.jsonl");
  ASSERT_EQ(journal.size(), 33u);
  size_t skipped = 0;
  for (const auto& j : journal) skipped += j.skipped.empty() ? 0 : 1;
  EXPECT_EQ(skipped, 17u - 5u);
  EXPECT_EQ(read_samples_csv(tmp / "run" / "samples.csv").size(), (33u - 12u) * 4u);
}

TEST(AdaptiveStop, BadUntilFieldsAreNamed) {
  for (const auto& [until, expect] : std::vector<std::pair<std::string, std::string>>{
           {"until: {angle_sigma_max_arcsec: -1}", "angle_sigma_max_arcsec"},
           {"until: {angle_sigma: 0.1}", "angle_sigma"},
           {"until: 0.1", "until"},
           {"until: {}", "angle_sigma_max_arcsec"}}) {
    Diagnostics d("bad.yaml");
    parse_procedure("steps:\n  - null_offset_grid: {extent_deg: 0.2, step_deg: 0.05, frames: 4, " + until + "}\n",
                    "bad.yaml", d);
    EXPECT_FALSE(d.empty()) << until;
    EXPECT_NE(d.text().find(expect), std::string::npos) << d.text();
    EXPECT_NE(d.text().find("bad.yaml:2"), std::string::npos) << d.text();
  }
}

}  // namespace
}  // namespace fpss
