// Several recordings diagnosed as one, the look-alike sets, the candidates' status and the planned
// run's predicted separation (calib/diagnosis/followup.h), on recordings of the simulated bench.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "base/errors.h"
#include "calib/diagnosis/diagnosis.h"
#include "calib/diagnosis/followup.h"
#include "fixtures/bench.h"
#include "fixtures/recording.h"
#include "tests/calib/diagnosis_recordings.h"

namespace fpss {
// Named, not anonymous: the unity build puts this file beside diagnosis_test.cpp.
namespace followup_test {

using diagnosis_test::bench;
using diagnosis_test::kSettle;
using diagnosis_test::options;
using diagnosis_test::plan;

DiagnosisColumns record(const BenchConfig& cfg, const SessionPlan& p, const std::string& origin) {
  Bench b(cfg);
  SampleTable t = record_session(b, p);
  t.origin = origin;
  return DiagnosisColumns::of(t);
}

const nlohmann::ordered_json* candidate(const Diagnosis& d, const std::string& name) {
  for (const auto& c : d.candidates) {
    if (c["name"] == name) return &c;
  }
  return nullptr;
}

TEST(JointDiagnosis, ASkewUnseenInDwellsIsNamedOnceASlewRecordingJoinsWithOneParameterForBoth) {
  const std::string skew = "time_skew:skew_s=0.004";
  DiagnosisColumns dwells = record(bench(3, {skew}), plan(true, false), "dwells.csv");
  const size_t first_rows = dwells.size();
  const Diagnosis alone = diagnose(dwells, default_bench_config().truth, options());
  EXPECT_NE(alone.cause, "time_skew");
  EXPECT_EQ(candidate(alone, "time_skew")->at("status"), "unbounded");

  std::vector<DiagnosisColumns> both;
  both.push_back(std::move(dwells));
  both.push_back(record(bench(4, {skew}), plan(false, true), "slews.csv"));
  const size_t second_rows = both.back().size();
  const Diagnosis d = diagnose(std::move(both), default_bench_config().truth, options());
  EXPECT_EQ(d.cause, "time_skew");
  ASSERT_FALSE(d.causes.empty());
  EXPECT_NEAR(d.causes[0].params["skew_s"].get<double>(), 0.004, 0.0004);
  EXPECT_EQ(candidate(d, "time_skew")->at("status"), "named");
  // Each recording keeps its own nuisance level (its noise floor), and its steps stay apart.
  ASSERT_EQ(d.recordings.size(), 2u);
  EXPECT_EQ(d.recordings[0].rows, first_rows);
  EXPECT_EQ(d.recordings[1].rows, second_rows);
  EXPECT_EQ(d.recordings[1].step_offset, kJointStepStride);
  // The slews alone have no dwell floor: their own floor comes from the slews' rows.
  for (const auto& p : d.recordings) EXPECT_GT(p.noise_floor_arcsec, 0.02) << p.source;
  // The held-out split spans the recordings: held-out steps of both.
  const auto ids = d.split["heldout_step_ids"].get<std::vector<int64_t>>();
  EXPECT_TRUE(std::any_of(ids.begin(), ids.end(), [](int64_t s) { return s < kJointStepStride; }));
  EXPECT_TRUE(std::any_of(ids.begin(), ids.end(), [](int64_t s) { return s >= kJointStepStride; }));
  EXPECT_EQ(d.to_json()["recordings"].size(), 2u);
}

TEST(JointDiagnosis, OneRecordingIsItsOwnJointAndTooManyOrForeignStepsAreRefused) {
  std::vector<DiagnosisColumns> none;
  EXPECT_THROW(join_recordings(std::move(none)), InputError);
  std::vector<DiagnosisColumns> many(kMaxJointRecordings + 1);
  EXPECT_THROW(join_recordings(std::move(many)), InputError);
  std::vector<DiagnosisColumns> two;
  two.push_back(record(bench(5, {}), plan(true, false), "a.csv"));
  two.push_back(record(bench(6, {}), plan(true, false), "b.csv"));
  two.back().step.back() = kJointStepStride;  // a step id that would run into the next recording's
  EXPECT_THROW(join_recordings(std::move(two)), InputError);
}

TEST(AmbiguousSets, ADriftWhoseTemperatureFollowsTimeIsASetWithTheTemperatureAndTheVerdictStays) {
  BenchConfig cfg = bench(61, {"temperature:pitch_arcsec_per_c=1.0,yaw_arcsec_per_c=1.0"});
  cfg.temperature.amplitude_c = 0;  // a plain ramp
  const Diagnosis d = diagnose(record(cfg, plan(true, false), "ramp.csv"), cfg.truth, options());
  EXPECT_EQ(d.cause, "drift");
  EXPECT_EQ(d.verdict, "explained");
  ASSERT_EQ(d.ambiguous.size(), 1u);
  EXPECT_EQ(d.ambiguous[0].members, (std::vector<std::string>{"drift", "temperature"}));
  EXPECT_TRUE(std::isnan(d.ambiguous[0].score_differences[1]));  // the look-alike could not be scored
  EXPECT_EQ(d.ambiguous[0].factor, "time");
  const auto j = d.to_json();
  EXPECT_TRUE(j["ambiguous"][0]["score_differences"]["temperature"].is_null());
  EXPECT_EQ(j["ambiguous"][0]["margin"], kAmbiguityMargin);
  EXPECT_EQ(candidate(d, "temperature")->at("status"), "ambiguous");
}

// Two runs on one bench whose drift goes on between them, each recorded as `run` writes it: its
// time_s from zero, the gimbal's clock beside it (bench_clock_s).
std::vector<DiagnosisColumns> two_runs_on_one_bench(const BenchConfig& cfg, bool with_gimbal_clock) {
  Bench b(cfg);
  std::vector<DiagnosisColumns> runs;
  for (const char* name : {"first.csv", "second.csv"}) {
    SampleTable t = record_session(b, plan(true, false));
    t.origin = name;
    DiagnosisColumns c = DiagnosisColumns::of(t);
    const double start = c.time_s.front();
    for (double& v : c.time_s) v -= start;
    if (with_gimbal_clock) c.bench_clock_s = start;
    runs.push_back(std::move(c));
    b.advance_to(b.time_s() + 300.0);  // diagnosing and designing between runs
  }
  return runs;
}

TEST(JointDiagnosis, RunsOnTheGimbalsClockShareOneBenchClockAndADriftBetweenThemIsOneDrift) {
  BenchConfig cfg = bench(71, {"drift:pitch_arcsec_per_s=0.004,yaw_arcsec_per_s=-0.003"});
  cfg.temperature.amplitude_c = 0;
  cfg.temperature.ramp_c_per_s = 0;  // drift alone changes with time
  std::vector<DiagnosisColumns> runs = two_runs_on_one_bench(cfg, true);
  const double second_start = runs[1].bench_clock_s, first_start = runs[0].bench_clock_s;
  const Diagnosis d = diagnose(std::move(runs), cfg.truth, options());
  ASSERT_EQ(d.recordings.size(), 2u);
  EXPECT_DOUBLE_EQ(d.recordings[0].time_shift_s, 0.0);
  EXPECT_NEAR(d.recordings[1].time_shift_s, second_start - first_start, 1e-9);
  EXPECT_GT(d.recordings[1].time_span_s[0], d.recordings[0].time_span_s[1] + 299.0);  // on the bench clock
  EXPECT_EQ(d.to_json()["recordings"][1]["clock"], "bench");
  EXPECT_EQ(d.cause, "drift");
  EXPECT_EQ(d.verdict, "explained");
  ASSERT_FALSE(d.causes.empty());
  EXPECT_NEAR(d.causes[0].params["pitch_arcsec_per_s"].get<double>(), 0.004, 0.0004);
  for (const auto& w : d.warnings) EXPECT_EQ(w.find("share no clock"), std::string::npos) << w;

  // Without the gimbal's clock each run starts again at zero: the diagnosis says so, and the
  // second run keeps a level of its own (where the drift had got to when it started), so the one
  // drift is still named from what each run shows.
  const Diagnosis own = diagnose(two_runs_on_one_bench(cfg, false), cfg.truth, options());
  EXPECT_EQ(own.to_json()["recordings"][1]["clock"], "own");
  EXPECT_TRUE(std::isnan(own.recordings[1].time_shift_s));
  EXPECT_TRUE(std::any_of(own.warnings.begin(), own.warnings.end(), [](const std::string& w) {
    return w.find("share no clock") != std::string::npos;
  }));
  EXPECT_EQ(own.cause, "drift");
  EXPECT_EQ(own.verdict, "explained");
  ASSERT_FALSE(own.causes.empty());
  EXPECT_NEAR(own.causes[0].params["pitch_arcsec_per_s"].get<double>(), 0.004, 0.0004);
  // The level: the drift at the second run's start on the bench clock, 0.004 x its start.
  const auto levels = own.causes[0].notes["recording_levels_arcsec"];
  ASSERT_EQ(levels.size(), 1u) << own.causes[0].notes.dump();
  EXPECT_NEAR(levels[0][0].get<double>(), 0.004 * (second_start - first_start), 0.15);
  // A bias shows in the first run only, where the second keeps its own level: a higher limit.
  EXPECT_GT(candidate(own, "bias")->at("limit_arcsec").get<double>(),
            1.2 * candidate(d, "bias")->at("limit_arcsec").get<double>());
}

TEST(AmbiguousSets, ATemperatureReadToTwoDecimalsOnASlowRampIsStillALookAlikeOfDrift) {
  // The emulator's default ramp (0.002 C/s) read once per point as `TEMP` gives it (two decimals):
  // what leaves a straight line in time is the reading's rounding, which a drift cannot be told
  // from; scoring it would prefer the smooth drift over the rounded readings, a confident wrong cause.
  BenchConfig cfg = bench(62, {"temperature:pitch_arcsec_per_c=5.0,yaw_arcsec_per_c=5.0"});
  cfg.temperature.amplitude_c = 0;
  cfg.temperature.ramp_c_per_s = 0.002;
  DiagnosisColumns c = record(cfg, plan(true, false), "ramp_read.csv");
  size_t first = 0;
  for (size_t i = 0; i < c.size(); ++i) {
    if (i > 0 && c.step[i] != c.step[i - 1]) first = i;
    c.temperature_c[i] = static_cast<float>(std::round(c.temperature_c[first] * 100.0) / 100.0);
  }
  const Diagnosis d = diagnose(std::move(c), cfg.truth, options());
  EXPECT_EQ(d.cause, "drift");
  ASSERT_EQ(d.ambiguous.size(), 1u);
  EXPECT_EQ(d.ambiguous[0].members, (std::vector<std::string>{"drift", "temperature"}));
  const auto* t = candidate(d, "temperature");
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->at("status"), "ambiguous");
  bool said = false;
  for (const auto& m : d.not_observable) said = said || (m.name == "temperature" && m.reason.find("0.01 C steps") != std::string::npos);
  EXPECT_TRUE(said) << "the reason names the reading's resolution";
}

TEST(AmbiguousSets, AClearCauseOnAFullRecordingHasNoSetAndBoundsWhatItCouldSee) {
  const BenchConfig cfg = bench(7, {"backlash:width_arcsec=1.5"});
  const Diagnosis d = diagnose(record(cfg, plan(true, true), "full.csv"), cfg.truth, options());
  EXPECT_EQ(d.cause, "backlash");
  EXPECT_TRUE(d.ambiguous.empty());
  EXPECT_EQ(candidate(d, "backlash")->at("status"), "named");
  // Every candidate's limit in arcsec where it acts, and a status from the end state's four.
  for (const auto& c : d.candidates) {
    const std::string s = c["status"];
    EXPECT_TRUE(s == "named" || s == "bounded" || s == "unbounded" || s == "ambiguous") << s;
    if (s == "bounded") {
      EXPECT_LE(c["limit_arcsec"].get<double>(), d.materiality_arcsec) << c.dump();
    }
  }
  EXPECT_NEAR(d.materiality_arcsec, d.noise_floor_arcsec / std::sqrt(20.0), 1e-9);
}

// The paper's offsets along each axis, every point reached through an unrecorded overshoot below it.
std::vector<SessionOp> one_sided_grid() {
  std::vector<SessionOp> ops;
  auto at = [&](double p, double y) {
    SessionOp over;
    over.pitch_arcsec = p - 300;
    over.yaw_arcsec = y - 300;
    ops.push_back(over);
    SessionOp dwell;
    dwell.kind = SessionOp::Kind::dwell;
    dwell.pitch_arcsec = p;
    dwell.yaw_arcsec = y;
    dwell.frames = 25;
    dwell.sample_rate_hz = 50;
    ops.push_back(dwell);
  };
  at(0, 0);
  for (int axis = 0; axis < 2; ++axis) {
    for (int k = -6; k <= 6; ++k) {
      if (k == 0) continue;
      at(axis == 0 ? k * 216.0 : 0, axis == 1 ? k * 216.0 : 0);
      at(0, 0);
    }
  }
  return ops;
}

TEST(RecordedApproach, AGridReachedThroughUnseenOvershootsReadsItsSidesFromTheApproachColumns) {
  auto run = [](const std::string& effect) {
    Bench b(bench(21, {effect}));
    SampleTable t = record_ops(b, one_sided_grid());
    t.origin = "one-sided.csv";
    return t;
  };
  // Settling rings after every approach, always the same way: named, with its amplitude.
  const SampleTable settled = run("settling:amplitude_arcsec=2,tau_s=0.6");
  ASSERT_TRUE(settled.has_column("approach_pitch"));
  const Diagnosis s = diagnose(settled, default_bench_config().truth, options());
  EXPECT_EQ(s.recording["approach_sides"], "recorded");
  EXPECT_EQ(s.cause, "settling") << s.to_json().dump(1);
  ASSERT_FALSE(s.causes.empty());
  EXPECT_NEAR(s.causes[0].params["amplitude_arcsec"].get<double>(), 2.0, 0.2);
  // Backlash from one side is a constant: a bias, with backlash beside it as its look-alike.
  const Diagnosis b = diagnose(run("backlash:width_arcsec=3"), default_bench_config().truth, options());
  EXPECT_NE(b.cause, "backlash");
  bool beside = false;
  for (const auto& set : b.ambiguous) {
    beside = beside || std::find(set.members.begin(), set.members.end(), "backlash") != set.members.end();
  }
  EXPECT_TRUE(beside) << b.to_json()["ambiguous"].dump();
}

TEST(PlannedRun, SlewsSeparateATimeShiftFromBacklashAndDwellsAloneDoNot) {
  EffectParams skew{"time_skew", {{"skew_s", 0.002}}, {}};
  EffectParams backlash{"backlash", {{"width_arcsec", 1.2}}, {}};
  const CoefficientSet model = default_bench_config().truth;
  BenchConfig quiet = bench(9, {});
  const PlannedRun slews(record(quiet, plan(true, true), "plan.csv"), model, options(), 0.07);
  const PlannedRun dwells(record(quiet, plan(true, false), "plan.csv"), model, options(), 0.07);
  EXPECT_GT(slews.separation(skew, backlash), 16.0);
  // At rest a time shift does nothing: backlash predicts the same as no skew at all.
  EXPECT_LT(dwells.expected_log_lr(skew, "backlash"), 1.0);
  // The limit of a time shift where it acts: finite with slews, none at rest.
  EXPECT_TRUE(std::isfinite(slews.limit_arcsec("time_skew", 0)));
  EXPECT_FALSE(std::isfinite(dwells.limit_arcsec("time_skew", 0)));
  // More rows that say nothing of it dilute what the plan shows.
  EXPECT_GT(slews.limit_arcsec("time_skew", 100000), slews.limit_arcsec("time_skew", 0));
  EXPECT_THROW(PlannedRun(record(quiet, plan(true, false), "plan.csv"), model, options(), 0.0), InputError);
}

TEST(PlannedRun, AnEffectFromGapJsonNeedsAKnownName) {
  EXPECT_EQ(effect_from_json({{"name", "bias"}, {"params", {{"pitch_arcsec", 1.0}, {"yaw_arcsec", 2.0}}}}).params.at("yaw_arcsec"), 2.0);
  EXPECT_THROW(effect_from_json({{"name", "gremlins"}}), InputError);
  EXPECT_THROW(effect_from_json(nlohmann::ordered_json::array()), InputError);
}

// The model's transfer function aged: each sinusoid's amplitude scaled by `amp` and phase moved by
// `phase_rad` (alternating signs), both axes.
BenchConfig aged_bench(uint64_t seed, double amp, double phase_rad) {
  BenchConfig cfg = bench(seed, {});
  Effect e{"coefficients", {}, {}};
  CoefficientSet s = cfg.truth;
  for (AxisCoeffs* c : {&s.alpha, &s.beta}) {
    (*c)[2] *= 1 + amp;
    (*c)[4] += phase_rad;
    (*c)[5] *= 1 - amp;
    (*c)[7] -= phase_rad;
  }
  e.coefficients = s;
  cfg.effects = {e};
  return cfg;
}

SessionPlan grid(double extent_deg, double step_deg) {
  SessionPlan p = plan(true, false);
  p.grids[0].extent_deg = extent_deg;
  p.grids[0].step_deg = step_deg;
  p.grids[0].samples_per_dwell = 25;
  return p;
}
SessionPlan narrow_grid() { return grid(0.05, 0.01); }
SessionPlan paper_grid() { return grid(0.42, 0.06); }

TEST(AmbiguousSets, AnAgedTransferFunctionOverANarrowGridPassesForABiasAndAScaleUntilOffsetsSpanTheRange) {
  const BenchConfig cfg = aged_bench(31, 0.05, 0.05);
  const Diagnosis narrow = diagnose(record(cfg, narrow_grid(), "narrow.csv"), cfg.truth, options());
  EXPECT_TRUE(std::none_of(narrow.causes.begin(), narrow.causes.end(),
                           [](const EffectResult& c) { return c.name == "coefficients"; }))
      << narrow.to_json()["causes"].dump();
  ASSERT_FALSE(narrow.ambiguous.empty()) << narrow.to_json().dump(1);
  const auto& set = narrow.ambiguous[0].members;
  EXPECT_NE(std::find(set.begin(), set.end(), "coefficients"), set.end());
  EXPECT_EQ(narrow.ambiguous[0].factor, "angle");
  EXPECT_EQ(candidate(narrow, "coefficients")->at("status"), "ambiguous");

  // The refit as GAP.json carries it predicts beyond its rows: offsets across the range would
  // separate it from the bias and scale factor; more of the narrow grid would not.
  const auto gap = narrow.to_json();
  const nlohmann::ordered_json* refit = nullptr;
  for (const auto& e : gap["effects"]) if (e["name"] == "coefficients") refit = &e;
  ASSERT_NE(refit, nullptr);
  const EffectParams aged = effect_from_json(*refit);
  ASSERT_TRUE(aged.coefficients.has_value());
  const BenchConfig quiet = bench(32, {});
  const PlannedRun wide(record(quiet, paper_grid(), "wide.csv"), cfg.truth, options(), narrow.noise_floor_arcsec);
  const PlannedRun same(record(quiet, narrow_grid(), "same.csv"), cfg.truth, options(), narrow.noise_floor_arcsec);
  const std::vector<std::string> rivals = {"bias", "scale_factor"};
  EXPECT_GT(wide.expected_log_lr(aged, rivals), 16.0);
  EXPECT_GT(wide.expected_log_lr(aged, rivals), 10 * same.expected_log_lr(aged, rivals));
  // The narrow grid reaches two sixths of the range on each axis, the paper's all six (its
  // held-out steps beyond the fit rows' reach judge nothing, and do not count).
  const auto reached = [](const RangeSections& s) {
    return std::count(s[0].begin(), s[0].end(), true) + std::count(s[1].begin(), s[1].end(), true);
  };
  EXPECT_EQ(reached(same.range_sections()), 4);
  EXPECT_EQ(reached(wide.range_sections()), 12);

  // Jointly with offsets over the range: the change of coefficients, measured where it acts.
  std::vector<DiagnosisColumns> both;
  both.push_back(record(cfg, narrow_grid(), "narrow.csv"));
  both.push_back(record(aged_bench(33, 0.05, 0.05), paper_grid(), "wide.csv"));
  const Diagnosis d = diagnose(std::move(both), cfg.truth, options());
  EXPECT_EQ(d.cause, "coefficients") << d.to_json()["causes"].dump();
  EXPECT_EQ(candidate(d, "coefficients")->at("status"), "named");
}

TEST(AmbiguousSets, ARefitNamedOverPartOfTheRangeIsNotYetAMeasurementOfIt) {
  // Aged enough that the narrow grid sees the curvature: the refit is named, but it extrapolates
  // over four sixths of the range on each axis.
  const BenchConfig cfg = aged_bench(34, 0.25, 0.3);
  const Diagnosis d = diagnose(record(cfg, narrow_grid(), "narrow.csv"), cfg.truth, options());
  ASSERT_EQ(d.cause, "coefficients") << d.to_json()["causes"].dump();
  const auto* c = candidate(d, "coefficients");
  EXPECT_EQ(c->at("status"), "unbounded");
  EXPECT_EQ(c->at("why").get<std::string>().rfind("named over part of the calibrated range only (pitch reaches 2 of 6", 0),
            0u)
      << c->dump();
}

TEST(PlannedRun, ARefitFromGapJsonCarriesItsCoefficientsWithinAFilesLimits) {
  nlohmann::ordered_json e = {{"name", "coefficients"},
                              {"params", {{"alpha", {1, 2, 3, 4, 5, 6, 7, 8}}, {"beta", {8, 7, 6, 5, 4, 3, 2, 1}}}}};
  const EffectParams p = effect_from_json(e);
  ASSERT_TRUE(p.coefficients.has_value());
  EXPECT_EQ(p.coefficients->beta[0], 8.0);
  e["params"]["beta"][3] = 1e9;
  EXPECT_THROW(effect_from_json(e), InputError);
  e["params"]["beta"][3] = "five";
  EXPECT_THROW(effect_from_json(e), InputError);
  e["params"]["beta"] = {1, 2};  // not a set: nothing to predict with
  EXPECT_FALSE(effect_from_json(e).coefficients.has_value());
}

// A sensor 60 ms late on dwells sampled from their arrival: the first frames of each dwell still
// see the end of the move, which no catalogued effect at rest is.
TEST(ArrivalGuard, ALaggingSensorsViewOfTheMoveEndIsNoSettlingOnceSlewsPinTheLag) {
  const BenchConfig cfg = bench(41, {"time_skew:skew_s=0.06"});
  SessionPlan from_arrival = paper_grid();
  from_arrival.grids[0].settle_s = 0;
  DiagnosisOptions o = options();
  o.settle_s = 0.005;
  const Diagnosis dwells = diagnose(record(cfg, from_arrival, "dwells.csv"), cfg.truth, o);
  EXPECT_GT(dwells.split["arriving_rows"].get<size_t>(), 0u);
  // Whatever a dwells-only recording names for it, a settling gone within the first frames is
  // never named alone: the lag it may be stands beside it.
  for (const auto& c : dwells.causes) {
    if (c.name != "settling") continue;
    bool beside = false;
    for (const auto& set : dwells.ambiguous) {
      beside = beside || std::find(set.members.begin(), set.members.end(), "time_skew") != set.members.end();
    }
    EXPECT_TRUE(beside) << dwells.to_json()["causes"].dump();
  }
  std::vector<DiagnosisColumns> both;
  both.push_back(record(cfg, from_arrival, "dwells.csv"));
  both.push_back(record(bench(42, {"time_skew:skew_s=0.06"}), plan(false, true), "slews.csv"));
  const Diagnosis d = diagnose(std::move(both), cfg.truth, o);
  ASSERT_EQ(d.causes.size(), 1u) << d.to_json()["causes"].dump();
  EXPECT_EQ(d.cause, "time_skew");
  EXPECT_NEAR(d.causes[0].params["skew_s"].get<double>(), 0.06, 0.003);
  EXPECT_EQ(d.verdict, "explained") << d.verdict_sentence;
  EXPECT_TRUE(std::any_of(d.warnings.begin(), d.warnings.end(),
                          [](const std::string& w) { return w.find("arrival guard was widened") != std::string::npos; }));
}

}  // namespace followup_test
}  // namespace fpss
