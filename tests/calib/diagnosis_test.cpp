// The gap diagnosis: forward models against the bench's physics, attribution, the paper's time
// skew, what cannot be observed, the split, bad input and the report.
#include "calib/diagnosis/diagnosis.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include "base/errors.h"
#include "calib/diagnosis/model.h"
#include "fixtures/bench.h"
#include "fixtures/recording.h"
#include "tests/calib/diagnosis_recordings.h"

namespace fpss {
namespace {

using diagnosis_test::bench;
using diagnosis_test::kSettle;
using diagnosis_test::options;
using diagnosis_test::plan;

SampleTable record(const BenchConfig& cfg, const SessionPlan& p = plan()) {
  Bench b(cfg);
  SampleTable t = record_session(b, p);
  t.origin = "test recording";
  return t;
}

std::string fmt_skew(double s) { return "time_skew:skew_s=" + std::to_string(s); }

EffectParams to_params(const Effect& e) {
  EffectParams p;
  p.name = e.name;
  p.params = e.params;
  p.coefficients = e.coefficients;
  return p;
}

// ------------------------------------------------------------------ forward models

TEST(DiagnosisForwardModel, EveryEffectPredictsWhatTheBenchSensorReads) {
  const std::vector<std::string> specs = {
      "bias:pitch_arcsec=2.5,yaw_arcsec=-1.5",
      "drift:pitch_arcsec_per_s=0.03,yaw_arcsec_per_s=-0.02",
      "scale_factor:pitch_ppm=1500,yaw_ppm=-800",
      "boresight_roll:roll_arcsec=400",
      "axis_nonorthogonality:skew_arcsec=-300",
      "backlash:width_arcsec=4",
      "settling:amplitude_arcsec=2,tau_s=0.6",
      "time_skew:skew_s=0.08",
      "temperature:pitch_arcsec_per_c=1.2,yaw_arcsec_per_c=-0.7",
  };
  std::vector<EffectParams> effects;
  for (const auto& s : specs) effects.push_back(to_params(parse_effect(s)));
  effects[8].params["t0_c"] = default_bench_config().temperature.t0_c;
  EffectParams coef;
  coef.name = "coefficients";
  coef.coefficients = default_bench_config().truth;
  coef.coefficients->alpha[2] *= 1.2;
  coef.coefficients->beta[7] += 0.2;
  effects.push_back(coef);

  for (const auto& e : effects) {
    SCOPED_TRACE(e.name);
    BenchConfig cfg = bench(3, {}, /*noisy=*/false);
    Effect be;
    be.name = e.name;
    be.params = e.params;
    be.params.erase("t0_c");
    be.coefficients = e.coefficients;
    cfg.effects = {be};
    const SampleTable t = record(cfg);
    const SensorPrediction p = predict_sensor(t, cfg.truth, e, options());
    const AxisModel am = cfg.truth.alpha_model(), bm = cfg.truth.beta_model();
    double worst = 0, effect_size = 0;
    size_t used = 0;
    for (size_t i = 0; i < t.size(); ++i) {
      if (!p.predictable[i]) continue;
      ++used;
      const double mp = am.angle_arcsec(t.counts_alpha[i]), my = bm.angle_arcsec(t.counts_beta[i]);
      worst = std::max({worst, std::abs(mp - p.pitch_arcsec[i]), std::abs(my - p.yaw_arcsec[i])});
      effect_size = std::max({effect_size, std::abs(mp - t.ref_pitch_arcsec[i]), std::abs(my - t.ref_yaw_arcsec[i])});
    }
    EXPECT_GT(used, t.size() * 8 / 10);
    // Integer counts: up to half a count (0.055 arcsec) off; the effect itself is far larger.
    EXPECT_LT(worst, 0.1);
    EXPECT_GT(effect_size, 1.0);
  }
}

// ------------------------------------------------------------------ attribution

TEST(Diagnosis, NoiseOnlyGivesNoneWithGapAfterEqualBefore) {
  for (uint64_t seed : {11u, 12u, 13u}) {
    const Diagnosis d = diagnose(record(bench(seed, {})), default_bench_config().truth, options());
    EXPECT_EQ(d.cause, "none") << "seed " << seed;
    EXPECT_TRUE(d.causes.empty());
    EXPECT_EQ(d.gap_after_arcsec, d.gap_before_arcsec);
    // The noise floor (within-dwell scatter) is what the residual is made of here.
    EXPECT_NEAR(d.noise_floor_arcsec, d.gap_before_arcsec, 0.15 * d.gap_before_arcsec);
    EXPECT_EQ(d.effects.size(), 11u);  // every candidate tried (all observable) and none
  }
}

// The coefficients candidate has a detection limit like the others: the RMS change of the angle
// that would have been material on the held-out rows, with its 16 parameters' penalty.
TEST(Diagnosis, CoefficientsHaveADetectionLimitInArcsec) {
  const Diagnosis d = diagnose(record(bench(12, {})), default_bench_config().truth, options());
  const auto it = std::find_if(d.effects.begin(), d.effects.end(), [](const EffectResult& e) { return e.name == "coefficients"; });
  ASSERT_NE(it, d.effects.end());
  ASSERT_TRUE(it->detection_limit.contains("angle_rms_arcsec")) << it->detection_limit.dump();
  const double N = 2.0 * d.split["heldout_rows"].get<double>(), nf = d.noise_floor_arcsec;
  const double want = nf * std::sqrt(std::max(0.1, std::expm1(16.0 * std::log(N) / N)));
  EXPECT_NEAR(it->detection_limit["angle_rms_arcsec"].get<double>(), want, 1e-9);
  EXPECT_GT(it->detection_limit["angle_rms_arcsec"].get<double>(), 0.3 * nf);
  EXPECT_LT(it->detection_limit["angle_rms_arcsec"].get<double>(), nf);
}

TEST(Diagnosis, PaperSlewCaseTimeSkewFoundLedBySlewRateWithin2ms) {
  for (double skew : {0.020, 0.050, 0.085, 0.120}) {
    SCOPED_TRACE(skew);
    const Diagnosis d = diagnose(record(bench(21, {fmt_skew(skew)})), default_bench_config().truth, options());
    ASSERT_EQ(d.cause, "time_skew");
    const double fitted = d.causes.front().params.at("skew_s").get<double>();
    std::printf("time skew %.3f s: fitted %.5f s (error %+.3f ms), where %s/%s %.1f %%, gap %.3f -> %.4f arcsec "
                "(noise %.4f)\n",
                skew, fitted, 1e3 * (fitted - skew), d.where.front().factor.c_str(), d.where.front().axis.c_str(),
                100 * d.where.front().share, d.gap_before_arcsec, d.gap_after_arcsec, d.noise_floor_arcsec);
    EXPECT_NEAR(fitted, skew, 0.002);
    ASSERT_FALSE(d.where.empty());
    EXPECT_EQ(d.where.front().factor, "slew_rate");
    EXPECT_GT(d.where.front().share, 0.5);
    EXPECT_LT(d.gap_after_arcsec, 1.5 * d.noise_floor_arcsec);
    EXPECT_GT(d.gap_before_arcsec, 10 * d.noise_floor_arcsec);
  }
}

TEST(Diagnosis, RollIsToldApartFromNonorthogonality) {
  const CoefficientSet m = default_bench_config().truth;
  const Diagnosis roll = diagnose(record(bench(31, {"boresight_roll:roll_arcsec=200"})), m, options());
  const Diagnosis skew = diagnose(record(bench(31, {"axis_nonorthogonality:skew_arcsec=200"})), m, options());
  EXPECT_EQ(roll.cause, "boresight_roll");
  EXPECT_EQ(skew.cause, "axis_nonorthogonality");
  EXPECT_NEAR(roll.causes.front().params.at("roll_arcsec").get<double>(), 200, 10);
  EXPECT_NEAR(skew.causes.front().params.at("skew_arcsec").get<double>(), 200, 10);
}

TEST(Diagnosis, TwoEffectsAreReportedInOrder) {
  const Diagnosis d = diagnose(record(bench(41, {"time_skew:skew_s=0.06", "bias:pitch_arcsec=2,yaw_arcsec=-1.5"})),
                               default_bench_config().truth, options());
  ASSERT_EQ(d.causes.size(), 2u);
  EXPECT_EQ(d.causes[0].name, "time_skew");  // alone, it explains more
  EXPECT_EQ(d.causes[1].name, "bias");
  EXPECT_EQ(d.cause, d.causes[0].name);
  EXPECT_GT(d.gap_after_arcsec, 1.5 * d.noise_floor_arcsec);  // one cause alone does not close it
  EXPECT_LT(d.gap_after_all_arcsec, 1.5 * d.noise_floor_arcsec);
  EXPECT_NEAR(d.causes[0].params.at("skew_s").get<double>(), 0.06, 0.002);
  EXPECT_NEAR(d.causes[1].params.at("pitch_arcsec").get<double>(), 2.0, 0.1);
  EXPECT_NEAR(d.causes[1].params.at("yaw_arcsec").get<double>(), -1.5, 0.1);
}

// Pairs whose best single is a stand-in (a settling with an endless tau for backlash plus drift;
// a temperature with a free reference for temperature plus bias): the pair search around a few
// singles still finds the two. (A bias equal to -k x a temperature shift is a temperature with
// another t0_c: that pair is not distinguishable and not asked for.)
TEST(Diagnosis, PairsFoundWhenTheBestSingleIsAStandIn) {
  const std::vector<std::pair<std::vector<std::string>, std::set<std::string>>> cases = {
      {{"backlash:width_arcsec=3", "drift:pitch_arcsec_per_s=0.02,yaw_arcsec_per_s=-0.015"}, {"backlash", "drift"}},
      {{"temperature:pitch_arcsec_per_c=1.5,yaw_arcsec_per_c=-1", "bias:pitch_arcsec=-3,yaw_arcsec=-2"},
       {"temperature", "bias"}},
      {{"backlash:width_arcsec=2", "bias:pitch_arcsec=1.5,yaw_arcsec=-2.5"}, {"backlash", "bias"}},
  };
  for (const auto& [effects, want] : cases) {
    SCOPED_TRACE(effects[0] + " + " + effects[1]);
    const Diagnosis d = diagnose(record(bench(43, effects)), default_bench_config().truth, options());
    std::set<std::string> got;
    for (const auto& c : d.causes) got.insert(c.name);
    EXPECT_EQ(got, want);
    EXPECT_LT(d.gap_after_all_arcsec, 1.5 * d.noise_floor_arcsec);
  }
}

// ------------------------------------------------------------------ what the data cannot tell

TEST(Diagnosis, TimeSkewWithoutMotionIsNotObservableNeverGuessed) {
  const Diagnosis d = diagnose(record(bench(51, {"time_skew:skew_s=0.1"}), plan(true, false)),
                               default_bench_config().truth, options());
  EXPECT_NE(d.cause, "time_skew");
  for (const auto& e : d.effects) EXPECT_NE(e.name, "time_skew");
  bool listed = false;
  for (const auto& n : d.not_observable) {
    if (n.name == "time_skew") {
      listed = true;
      EXPECT_NE(n.reason.find("motion"), std::string::npos) << n.reason;
      EXPECT_TRUE(n.incomplete_recording);
    }
  }
  EXPECT_TRUE(listed);
  EXPECT_TRUE(d.incomplete_recording());
  const auto j = d.to_json();
  ASSERT_TRUE(j.contains("not_observable"));
  EXPECT_EQ(j["not_observable"][0]["name"], "time_skew");
}

TEST(Diagnosis, LinearTemperatureRampCannotBeToldFromDrift) {
  BenchConfig cfg = bench(61, {"temperature:pitch_arcsec_per_c=1.0,yaw_arcsec_per_c=-1.0"});
  cfg.temperature.amplitude_c = 0;  // a plain ramp: temperature is a linear function of time
  const Diagnosis d = diagnose(record(cfg), cfg.truth, options());
  EXPECT_EQ(d.cause, "drift");
  bool listed = false;
  for (const auto& n : d.not_observable) {
    if (n.name == "temperature") {
      listed = true;
      EXPECT_NE(n.reason.find("drift"), std::string::npos) << n.reason;
    }
  }
  EXPECT_TRUE(listed);
}

TEST(Diagnosis, NoOffsetsLeavesAngleEffectsNotObservable) {
  SessionPlan p = plan(false, true);
  GridPlan nulls;  // two grids without offsets: null dwells only
  nulls.extent_deg = 0.0;
  nulls.samples_per_dwell = 20;
  nulls.sample_rate_hz = 50;
  p.grids = {nulls, nulls};
  const Diagnosis d = diagnose(record(bench(71, {"scale_factor:pitch_ppm=1000,yaw_ppm=1000"}), p),
                               default_bench_config().truth, options());
  std::set<std::string> missing;
  for (const auto& n : d.not_observable) if (n.incomplete_recording) missing.insert(n.name);
  for (const char* e : {"scale_factor", "boresight_roll", "axis_nonorthogonality", "coefficients"}) {
    EXPECT_TRUE(missing.count(e)) << e;
  }
  EXPECT_TRUE(d.incomplete_recording());
  EXPECT_NE(d.cause, "scale_factor");
}

TEST(Diagnosis, ASingleDwellIsBadInputNamingWhatCannotBeToldApart) {
  SessionPlan p;
  GridPlan one;
  one.extent_deg = 0.0;  // the null dwell only
  one.samples_per_dwell = 30;
  p.grids = {one};
  const SampleTable t = record(bench(81, {}), p);
  try {
    diagnose(t, default_bench_config().truth, options());
    FAIL() << "expected a DataError";
  } catch (const DataError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("dwell"), std::string::npos) << m;
    EXPECT_NE(m.find("bias"), std::string::npos) << m;
    EXPECT_NE(m.find("test recording"), std::string::npos) << m;
  }
  EXPECT_THROW(diagnose(SampleTable{}, default_bench_config().truth), DataError);
}

// ------------------------------------------------------------------ split and output

TEST(Diagnosis, SplitKeepsEveryStepWholeAndBothSidesCoverDwellsAndSlews) {
  const SampleTable t = record(bench(91, {}));
  const diag::Recording r = diag::prepare(DiagnosisColumns::of(t), default_bench_config().truth, options());
  size_t fit_d = 0, held_d = 0, fit_m = 0, held_m = 0;
  for (const auto& s : r.steps) {
    std::set<diag::Use> uses;
    for (size_t i = s.begin; i < s.end; ++i) if (r.use[i] != diag::Use::excluded) uses.insert(r.use[i]);
    EXPECT_LE(uses.size(), 1u) << "step " << s.id << " split across fit and held-out";
    const bool dwell = s.kind == diag::StepKind::dwell;
    (s.heldout ? (dwell ? held_d : held_m) : (dwell ? fit_d : fit_m))++;
  }
  EXPECT_GT(held_d, 0u);
  EXPECT_GT(held_m, 0u);
  EXPECT_GT(fit_d, held_d);
  EXPECT_GT(fit_m, held_m);
  EXPECT_EQ(r.motions, 8u);  // 2 axes x 2 rates x there and back
  // The split as reported.
  const Diagnosis d = diagnose(t, default_bench_config().truth, options());
  EXPECT_EQ(d.split["heldout_steps"]["dwells"].get<size_t>(), held_d);
  EXPECT_EQ(d.split["heldout_rows"].get<size_t>(), r.heldout_rows.size());
}

TEST(Diagnosis, GapJsonCarriesTheContractKeysInTheEmulatorsNames) {
  const Diagnosis d = diagnose(record(bench(101, {"backlash:width_arcsec=3"})), default_bench_config().truth, options());
  const auto j = d.to_json();
  for (const char* k : {"cause", "causes", "gap_before_arcsec", "gap_after_arcsec", "noise_floor_arcsec", "where", "effects",
                        "split", "not_observable"}) {
    EXPECT_TRUE(j.contains(k)) << k;
  }
  EXPECT_EQ(j["cause"], "backlash");
  const std::set<std::string> factors = {"constant", "angle", "cross_angle", "slew_rate", "approach_direction",
                                         "time", "time_since_move", "temperature"};
  ASSERT_FALSE(j["where"].empty());
  EXPECT_EQ(j["where"][0]["factor"], "approach_direction");
  for (const auto& w : j["where"]) {
    EXPECT_TRUE(factors.count(w["factor"].get<std::string>())) << w.dump();
    EXPECT_TRUE(w["axis"] == "pitch" || w["axis"] == "yaw" || w["axis"] == "both") << w.dump();
    EXPECT_GE(w["share"].get<double>(), 0.0);
    EXPECT_LE(w["share"].get<double>(), 1.0 + 1e-9);
    EXPECT_FALSE(w["detail"].get<std::string>().empty());
  }
  // Every effect's params use exactly the emulator's keys (temperature adds its reference t0_c).
  double prev = -1e300;
  for (const auto& e : j["effects"]) {
    const std::string name = e["name"];
    EXPECT_GE(e["score"].get<double>(), prev);  // ranked
    prev = e["score"].get<double>();
    EXPECT_TRUE(e.contains("heldout_rms_arcsec"));
    if (name == "none") continue;
    std::set<std::string> keys;
    for (auto it = e["params"].begin(); it != e["params"].end(); ++it) keys.insert(it.key());
    std::set<std::string> want;
    for (const auto& k : effect_catalogue().at(name)) want.insert(k);
    if (name == "coefficients") want = {"alpha", "beta"};
    if (name == "temperature") want.insert("t0_c");
    EXPECT_EQ(keys, want) << name;
  }
  EXPECT_NEAR(j["causes"][0]["params"]["width_arcsec"].get<double>(), 3.0, 0.1);
  // No time_since_move_s column: GAP.json says the arrivals were assumed, and a warning says from what.
  EXPECT_EQ(j["recording"]["arrival_times"], "assumed settle_s");
}

// A recording with its arrival times (time_since_move_s, as `run` records them): GAP.json says
// they were recorded, and no warning asks for them.
TEST(Diagnosis, RecordedArrivalTimesAreSaidToBeRecorded) {
  const SampleTable t = record(bench(103, {"settling:amplitude_arcsec=3,tau_s=0.4"}));
  DiagnosisColumns c = DiagnosisColumns::of(t);
  c.time_since_move_s.assign(t.size(), std::numeric_limits<float>::quiet_NaN());
  for (size_t i = 0; i < t.size(); ++i) {
    if (t.phase[i] == Phase::slew || t.phase[i] == Phase::move) continue;
    size_t first = i;
    while (first > 0 && t.step[first - 1] == t.step[i]) --first;
    c.time_since_move_s[i] = static_cast<float>(t.time_s[i] - t.time_s[first] + kSettle + 0.005);
  }
  const Diagnosis d = diagnose(std::move(c), default_bench_config().truth, options());
  const auto j = d.to_json();
  EXPECT_EQ(j["recording"]["arrival_times"], "recorded");
  for (const auto& w : d.warnings) EXPECT_EQ(w.find("no time_since_move_s"), std::string::npos) << w;
  EXPECT_EQ(d.cause, "settling");
}

// Outlier frames (1.5 % of the frames, a wild count on one axis) are reported and kept out of
// every fit: the parameters stay within 2 % of the same recording without them, and the verdict
// is never no_gap (nor explained: something outside the catalogue is there).
TEST(DiagnosisVerdict, OutlierFramesAreReportedAndKeptOutOfEveryFit) {
  for (const std::string spec : {"backlash:width_arcsec=2", "settling:amplitude_arcsec=3,tau_s=0.5", ""}) {
    SCOPED_TRACE(spec);
    const SampleTable clean = record(bench(321, spec.empty() ? std::vector<std::string>{} : std::vector<std::string>{spec}));
    SampleTable spiky = clean;
    int spikes = 0;
    for (size_t i = 0; i < spiky.size(); ++i) {
      const uint64_t h = splitmix64(i * 7919 + 13);
      if (h % 1000 >= 15) continue;  // 1.5 %
      const double counts = (20.0 + static_cast<double>(h % 400) / 10.0) * ((h >> 20) % 2 ? 1 : -1);
      ((h >> 30) % 2 ? spiky.counts_alpha : spiky.counts_beta)[i] += std::round(counts);
      ++spikes;
    }
    const Diagnosis a = diagnose(clean, default_bench_config().truth, options());
    const Diagnosis b = diagnose(spiky, default_bench_config().truth, options());
    EXPECT_EQ(a.outliers, 0);
    EXPECT_GE(b.outliers, spikes * 9 / 10);
    EXPECT_LE(b.outliers, spikes + 3);
    EXPECT_NE(b.verdict, "no_gap");
    EXPECT_NE(b.verdict, "explained");
    EXPECT_EQ(b.cause, a.cause);
    if (spec.empty()) {
      EXPECT_EQ(a.verdict, "no_gap");
      EXPECT_EQ(b.verdict, "unexplained");
      continue;
    }
    EXPECT_EQ(a.verdict, "explained");
    EXPECT_EQ(b.verdict, "partly_explained");
    ASSERT_FALSE(b.causes.empty());
    for (auto it = a.causes.front().params.begin(); it != a.causes.front().params.end(); ++it) {
      const double pa = it.value().get<double>(), pb = b.causes.front().params.at(it.key()).get<double>();
      EXPECT_NEAR(pb, pa, 0.02 * std::abs(pa)) << it.key();
    }
  }
}

// A host that reads the gimbal less often than frames come (a loaded machine at a high speed-up)
// gives runs of frames one reference reading; at 1000x most dwells have one reading for all their
// frames. Such frames agree with each other to the sensor's noise alone: they must neither shrink
// the sigma that frames with readings of their own are judged by (no outlier in a noise-only
// recording, real spikes still found) nor the noise floor (no gap, no cause). 60 % of the dwell
// frames on the reading before, and every dwell on one reading.
TEST(DiagnosisVerdict, FramesThatShareOneReadingAreNoOutliersAndKeepTheNoiseFloor) {
  for (uint64_t seed : {323u, 324u, 325u}) {
    const SampleTable own = record(bench(seed, {}), plan(true, false));
    const Diagnosis base = diagnose(own, default_bench_config().truth, options());
    for (const int percent : {60, 100}) {
      SCOPED_TRACE(fmt::format("seed {}, {} % shared", seed, percent));
      SampleTable t = own;
      size_t shared = 0, dwell_rows = 0;
      for (size_t i = 1; i < t.size(); ++i) {
        const bool dwell = t.phase[i] == Phase::null || t.phase[i] == Phase::offset;
        dwell_rows += dwell;
        if (!dwell || t.step[i] != t.step[i - 1] || static_cast<int>(splitmix64(seed * 1000003 + i) % 100) >= percent) continue;
        t.ref_pitch_arcsec[i] = t.ref_pitch_arcsec[i - 1];  // at rest: the previous frame's reading
        t.ref_yaw_arcsec[i] = t.ref_yaw_arcsec[i - 1];
        ++shared;
      }
      ASSERT_GT(shared, dwell_rows * (percent - 10) / 100);
      const Diagnosis d = diagnose(t, default_bench_config().truth, options());
      EXPECT_EQ(d.outliers, 0);
      EXPECT_EQ(d.verdict, "no_gap") << d.verdict_sentence;
      EXPECT_NEAR(d.noise_floor_arcsec / base.noise_floor_arcsec, 1.0, 0.1);
      if (percent == 100) continue;
      SampleTable spiky = t;
      int spikes = 0;
      for (size_t i = 0; i < spiky.size(); i += 97) {
        spiky.counts_alpha[i] += 30;
        ++spikes;
      }
      const Diagnosis s = diagnose(spiky, default_bench_config().truth, options());
      EXPECT_GE(s.outliers, spikes * 9 / 10);
      EXPECT_LE(s.outliers, spikes + 3);
    }
  }
}

// A model file's expected scatter: excess_scatter reported; noise the model does not know (here
// a model that expects a third of the bench's scatter) is a gap of its own (within_step).
TEST(DiagnosisVerdict, ExcessScatterIsAGapOfItsOwn) {
  const BenchConfig cfg = bench(322, {});
  const SampleTable t = record(cfg);
  CoefficientSet m = cfg.truth;
  m.extra["expected_scatter_arcsec"] = expected_scatter_arcsec(cfg);
  const Diagnosis ok = diagnose(t, m, options());
  EXPECT_NEAR(ok.excess_scatter(), 1.0, 0.15);
  EXPECT_EQ(ok.verdict, "no_gap");
  for (const auto& e : ok.effects) {
    if (e.name == "none" || e.name == "coefficients") continue;
    EXPECT_FALSE(e.detection_limit.empty()) << e.name;  // every observable candidate has its limit
  }
  m.extra["expected_scatter_arcsec"] = expected_scatter_arcsec(cfg) / 3;
  const Diagnosis low = diagnose(t, m, options());
  EXPECT_GT(low.excess_scatter(), 2.0);
  EXPECT_EQ(low.verdict, "unexplained");
  ASSERT_TRUE(low.unexplained.has_value());
  ASSERT_FALSE(low.unexplained->where.empty());
  EXPECT_EQ(low.unexplained->where.front().factor, "within_step");
  m.extra["expected_scatter_arcsec"] = "much";
  EXPECT_THROW(diagnose(t, m, options()), InputError);
}

}  // namespace
}  // namespace fpss
