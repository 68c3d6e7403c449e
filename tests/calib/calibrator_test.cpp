// The calibrator on bench recordings: the report, the methods, the start set, and data it must refuse.
#include "calib/calibrator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "base/errors.h"
#include "calib/report.h"
#include "fixtures/recording.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

SampleTable recording(const std::string& truth, GridPlan plan = {}, uint64_t seed = 5) {
  BenchConfig cfg = default_bench_config();
  cfg.truth = load_published(truth);
  cfg.seed = seed;
  return simulate_null_offset(cfg, plan);
}

CalibrationOptions one_thread() {
  CalibrationOptions o;
  o.threads = 1;
  return o;
}

double max_error(const AxisFit& f, const AxisCoeffs& truth) {
  return compare_transfer(f.coeffs, truth, f.counts_range[0], f.counts_range[1]).max_abs_arcsec;
}

std::string data_error_of(const SampleTable& t, CalibrationOptions o = one_thread()) {
  return test::error_of<DataError>([&] { calibrate(t, o); });
}

SampleTable without(const SampleTable& t, Phase phase) {
  SampleTable r;
  r.origin = t.origin;
  for (size_t i = 0; i < t.size(); ++i) {
    if (t.phase[i] != phase) r.push_back(t.row(i));
  }
  return r;
}

TEST(Calibrator, ReportsTableOneFiguresAndTheSolver) {
  const SampleTable t = recording("a-4-fpss2");
  const CalibrationReport r = calibrate(t, one_thread());
  EXPECT_EQ(r.samples, t.size());
  EXPECT_EQ(r.null_dwells, 29u);
  EXPECT_EQ(r.offset_dwells, 28u);
  EXPECT_EQ(r.pairs, 56u);  // every offset against the null before and after it
  for (const AxisFit* a : {&r.pitch, &r.yaw}) {
    EXPECT_EQ(a->residuals.points, 56u);
    EXPECT_NEAR(a->residuals.range_deg[0], -0.42, 0.001);
    EXPECT_NEAR(a->residuals.range_deg[1], 0.42, 0.001);
    // Per-dwell noise ~0.03 arcsec, a change carries two dwells.
    EXPECT_GT(a->residuals.rms_arcsec, 0.01);
    EXPECT_LT(a->residuals.rms_arcsec, 0.08);
    EXPECT_LE(a->residuals.mean_abs_arcsec, a->residuals.rms_arcsec);
    EXPECT_GE(a->residuals.max_abs_arcsec, a->residuals.rms_arcsec);
    EXPECT_GT(a->residuals.sd_arcsec, 0.0);
    EXPECT_LT(a->counts_range[0], -12000);
    EXPECT_GT(a->counts_range[1], 12000);
    EXPECT_TRUE(a->solver.converged) << a->solver.brief;
    EXPECT_GE(a->solver.candidates, 1u);
    EXPECT_NE(a->solver.brief.find("Ceres Solver Report"), std::string::npos);
    EXPECT_LE(a->solver.final_cost, a->solver.initial_cost);
    EXPECT_NE(a->solver.start.find("grid node"), std::string::npos);
    // 1-sigma of the angle is of the order of the per-dwell noise, and positive.
    EXPECT_GT(a->angle_sigma_max_arcsec, 0.005);
    EXPECT_LT(a->angle_sigma_max_arcsec, 0.1);
    EXPECT_FALSE(a->covariance_note.empty());
    for (double s : a->sigma) EXPECT_TRUE(std::isfinite(s));
  }
  EXPECT_EQ(r.pitch.axis, "pitch");
  EXPECT_EQ(r.yaw.coefficient_key, "beta");
  // The residual RMS agrees with what the solver minimised.
  EXPECT_NEAR(r.pitch.residuals.rms_arcsec, std::sqrt(2 * r.pitch.solver.final_cost / 56), 1e-9);
}

TEST(Calibrator, CoefficientSetCarriesTheResidualsBlock) {
  CalibrationOptions o = one_thread();
  o.unit = "FPSS2";
  const CalibrationReport r = calibrate(recording("a-6-fpss2"), o);
  const CoefficientSet s = r.coefficients();
  EXPECT_EQ(s.unit, "FPSS2");
  EXPECT_EQ(s.alpha, r.pitch.coeffs);
  EXPECT_EQ(s.beta, r.yaw.coeffs);
  const auto& res = s.extra.at("residuals");
  for (const char* axis : {"pitch", "yaw"}) {
    const auto& a = res.at(axis);
    for (const char* k : {"mean_abs_arcsec", "sd_arcsec", "max_abs_arcsec"}) EXPECT_TRUE(a.at(k).is_number_float());
    EXPECT_EQ(a.at("points").get<size_t>(), 56u);
    ASSERT_EQ(a.at("range_deg").size(), 2u);
    EXPECT_LT(a.at("range_deg")[0].get<double>(), a.at("range_deg")[1].get<double>());
  }
  EXPECT_EQ(s.extra.at("method"), "differences");
  EXPECT_EQ(s.extra.at("uncertainties").at("alpha").size(), 8u);
  EXPECT_TRUE(s.extra.at("solver").at("yaw").at("brief").is_string());
  // What is written parses back as a coefficient file (the format's validation).
  const CoefficientSet back = parse_coefficients(nlohmann::json::parse(to_json(s).dump()), "mem");
  EXPECT_EQ(back.alpha, s.alpha);
  const std::string text = summary_text(r);
  EXPECT_NE(text.find("pitch (alpha)"), std::string::npos) << text;
  EXPECT_NE(text.find("0.42 to -0.42"), std::string::npos) << text;
}

// Each listed angle's budget: its sources' root sum of squares is that angle's sigma (the noise
// model's covariance split by source must add up to the whole), the sources are the GUM's, and
// the JSON carries U = k u per angle with the worst angle's budget.
void expect_budget_adds_up(const AxisFit& a) {
  ASSERT_EQ(a.angle_budget.size(), a.angle_sigma_arcsec.size());
  for (size_t i = 0; i < a.angle_budget.size(); ++i) {
    const double sigma = a.angle_sigma_arcsec[i][1];
    ASSERT_FALSE(a.angle_budget[i].empty()) << i;
    EXPECT_NEAR(combine(a.angle_budget[i]).u, sigma, 1e-6 * sigma) << a.axis << " angle " << a.angle_sigma_arcsec[i][0];
  }
}

TEST(Calibrator, EveryListedAngleHasABudgetThatAddsUpToItsSigma) {
  const CalibrationReport r = calibrate(recording("a-6-fpss1"), one_thread());
  for (const AxisFit* a : {&r.pitch, &r.yaw}) {
    expect_budget_adds_up(*a);
    const std::vector<BudgetEntry>& b = a->angle_budget.back();
    // The emulated bench's temperature ramps (0.002 C/s) and moves nothing: the fitted sensitivity
    // is noise, and its entry says how large an effect the recording cannot exclude.
    ASSERT_TRUE(a->temperature.known);
    EXPECT_LT(std::abs(a->temperature.sensitivity_arcsec_per_c), 4 * a->temperature.sensitivity_sigma);
    ASSERT_EQ(b.size(), 5u);
    EXPECT_EQ(b[4].source.rfind("temperature", 0), 0u);
    EXPECT_EQ(b[0].source, "sensor noise");
    EXPECT_EQ(b[0].type, 'A');  // the count noise came from the within-dwell scatter
    EXPECT_TRUE(std::isfinite(b[0].dof));
    EXPECT_EQ(b[1].source, "quantisation");
    EXPECT_EQ(b[1].type, 'B');
    EXPECT_EQ(b[2].source, "reference noise");
    EXPECT_EQ(b[3].source, "model and fit");
    // The bench's count noise (0.3 counts) is near one LSB: rounding adds as much as the noise.
    EXPECT_GT(b[0].u, 0.0);
    EXPECT_GT(b[1].u, 0.0);
    if (!a->model_remainder) {
      EXPECT_EQ(b[3].u, 0.0);
    }
  }
  const nlohmann::json u = r.coefficients().extra.at("uncertainties").at("pitch");
  const double k = u.at("coverage_factor").get<double>();
  EXPECT_GE(k, 1.96);
  EXPECT_LT(k, 2.1);  // many degrees of freedom
  const auto& list = u.at("angle_expanded_uncertainty_arcsec");
  ASSERT_EQ(list.size(), r.pitch.angle_sigma_arcsec.size());
  double worst = 0;
  for (size_t i = 0; i < list.size(); ++i) {
    EXPECT_EQ(list[i][0].get<double>(), r.pitch.angle_sigma_arcsec[i][0]);
    const double big_u = list[i][1].get<double>();
    EXPECT_GE(big_u, 1.96 * r.pitch.angle_sigma_arcsec[i][1] * (1 - 1e-9));
    worst = std::max(worst, big_u);
  }
  EXPECT_EQ(u.at("expanded_uncertainty_max_arcsec").get<double>(), worst);
  ASSERT_EQ(u.at("budget").size(), 5u);
  const auto& temp = u.at("temperature");
  EXPECT_EQ(temp.at("reference_c").get<double>(), r.pitch.temperature.reference_c);
  EXPECT_EQ(temp.at("sensitivity_arcsec_per_c").get<double>(), r.pitch.temperature.sensitivity_arcsec_per_c);
  for (const auto& e : u.at("budget")) {
    for (const char* key : {"source", "type", "u_arcsec"}) EXPECT_TRUE(e.contains(key)) << e.dump();
  }
}

TEST(Calibrator, AGivenCountNoiseIsTypeBAndTheReferencesTermsJoinTheBudget) {
  CalibrationOptions o = one_thread();
  o.count_noise_counts = 0.5;
  o.count_noise_source = "caller";
  nlohmann::json term = {{"value", 0.0}, {"u", 1.0}};
  nlohmann::json axis = {{"scale_factor_ppm", {{"value", 0.0}, {"u", 50.0}}},
                         {"nonorthogonality_arcsec", term},
                         {"zero_arcsec", {{"value", 0.0}, {"u", 0.01}}},
                         {"cyclic", nlohmann::json::array({{{"harmonic", 2},
                                                            {"amplitude_arcsec", {{"value", 0.1}, {"u", 0.02}}},
                                                            {"phase_rad", {{"value", 0.3}, {"u", 0.1}}}}})}};
  o.reference = parse_reference_calibration(
      {{"certificate", "C-1"}, {"date", "2026-01-01"}, {"lab", "lab"}, {"pitch", axis}, {"yaw", axis}}, "ref.json");
  const CalibrationReport r = calibrate(recording("a-6-fpss1"), o);
  for (const AxisFit* a : {&r.pitch, &r.yaw}) {
    expect_budget_adds_up(*a);
    const std::vector<BudgetEntry>& b = a->angle_budget.back();
    // The fit's four and the temperature (the bench's ramp), then scale, non-orthogonality, zero,
    // amplitude, phase.
    ASSERT_EQ(b.size(), 5u + 5u);
    EXPECT_EQ(b[0].type, 'B');
    EXPECT_FALSE(std::isfinite(b[0].dof));
    EXPECT_EQ(b[4].source.rfind("temperature", 0), 0u);
    EXPECT_EQ(b[5].source, "reference calibration: " + a->axis + " scale factor");
    EXPECT_EQ(b[9].source, "reference calibration: " + a->axis + " cyclic harmonic 2 phase");
    // 50 ppm of the largest angle (0.42 deg = 1512 arcsec) is 0.0756 arcsec.
    EXPECT_NEAR(b[5].u, 50e-6 * std::abs(a->angle_sigma_arcsec.back()[0]), 1e-9);
    for (size_t i = 5; i < b.size(); ++i) EXPECT_EQ(b[i].type, 'B');
  }
}

TEST(Calibrator, AbsoluteMethodFitsC1ToC8AndNeedsNoNulls) {
  const auto truth = load_published("a-2-fpss1");
  const SampleTable t = recording("a-2-fpss1");
  CalibrationOptions o = one_thread();
  o.method = Method::absolute;
  const CalibrationReport r = calibrate(t, o);
  EXPECT_EQ(r.pitch.residuals.points, 57u);  // one per dwell
  EXPECT_LT(max_error(r.pitch, truth.alpha), 0.1);
  EXPECT_LT(max_error(r.yaw, truth.beta), 0.1);
  const CalibrationReport rn = calibrate(without(t, Phase::null), o);
  EXPECT_EQ(rn.pitch.residuals.points, 28u);
  EXPECT_LT(max_error(rn.pitch, truth.alpha), 0.15);
}

TEST(Calibrator, StartSetIsTriedAndAgrees) {
  const auto truth = load_published("a-5-fpss2");
  const SampleTable t = recording("a-5-fpss2");
  const CalibrationReport plain = calibrate(t, one_thread());
  CalibrationOptions o = one_thread();
  o.init = truth;
  const CalibrationReport with = calibrate(t, o);
  EXPECT_EQ(with.pitch.solver.candidates, plain.pitch.solver.candidates + 1);
  EXPECT_EQ(with.unit, "FPSS2");
  // Same minimum either way (within what the solver's tolerances allow).
  EXPECT_LT(compare_transfer(with.pitch.coeffs, plain.pitch.coeffs, -13000, 13000).max_abs_arcsec, 1e-3);
  EXPECT_LT(compare_transfer(with.yaw.coeffs, plain.yaw.coeffs, -13000, 13000).max_abs_arcsec, 1e-3);
  // A start far from the truth (prelaunch, one and two cycles over the range) alone is not trusted:
  // the grid's nodes still win.
  o.init = load_published("a-1-fpss1");
  const CalibrationReport far = calibrate(t, o);
  EXPECT_LT(max_error(far.pitch, truth.alpha), 0.1);
}

TEST(Calibrator, SlewRowsAreIgnored) {
  BenchConfig cfg = default_bench_config();
  cfg.seed = 9;
  Bench bench(cfg);
  SessionPlan plan;
  plan.grids.push_back(GridPlan{});
  plan.slews.push_back(SlewPlan{0, 1500.0, 300.0, 0.1});
  const SampleTable t = record_session(bench, plan);
  const SampleTable no_slews = without(t, Phase::slew);
  ASSERT_LT(no_slews.size(), t.size());
  const CalibrationReport a = calibrate(t, one_thread()), b = calibrate(no_slews, one_thread());
  EXPECT_EQ(a.pitch.coeffs, b.pitch.coeffs);
  EXPECT_EQ(a.yaw.coeffs, b.yaw.coeffs);
}

TEST(Calibrator, BoundedGridAndScreeningStagesStillRecover) {
  // Tiny caps force the strided paths the large recordings take.
  GridPlan plan;
  plan.step_deg = 0.03;
  const auto truth = load_published("a-6-fpss1");
  const SampleTable t = recording("a-6-fpss1", plan);
  CalibrationOptions o = one_thread();
  o.grid_max_rows = 40;
  o.screen_max_rows = 50;
  const CalibrationReport r = calibrate(t, o);
  EXPECT_EQ(r.pitch.residuals.points, 112u);  // the refinement still uses every change
  EXPECT_LE(r.pitch.solver.grid_rows, 42u);
  EXPECT_GE(r.pitch.solver.grid_rows, 38u);
  EXPECT_LT(max_error(r.pitch, truth.alpha), 0.1);
  EXPECT_LT(max_error(r.yaw, truth.beta), 0.1);
}

// Offsets alternating pitch, yaw, pitch, ... each between two nulls: changes come in a period of
// four (pitch forward, pitch back, yaw forward, yaw back). Built from the truth's inverse
// directly, since the bench's sessions do all pitch offsets first.
SampleTable alternating(const CoefficientSet& truth, int offsets, uint64_t seed) {
  const AxisModel a = truth.alpha_model(), b = truth.beta_model();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  SampleTable t;
  int64_t step = 0;
  double time = 0;
  for (int k = 0; k <= 2 * offsets; ++k) {
    const bool offset = k % 2 == 1, pitch = k % 4 == 1;
    const double ref = offset ? 3600 * (-0.42 + 0.84 * ((k / 2 * 7919) % offsets) / (offsets - 1)) : 0.0;
    const double p = offset && pitch ? ref : 0.0, y = offset && !pitch ? ref : 0.0;
    const double na = a.counts_for_angle(arcsec_to_rad(p)), nb = b.counts_for_angle(arcsec_to_rad(y));
    ++step;
    for (int i = 0; i < 5; ++i) {
      t.push_back(Sample{time += 0.1, offset ? Phase::offset : Phase::null, step, p + 0.05 * g(rng),
                         y + 0.05 * g(rng), std::round(na + 0.3 * g(rng)), std::round(nb + 0.3 * g(rng))});
    }
  }
  return t;
}

TEST(Calibrator, SubsetsDoNotAliasWithAPeriodicRecording) {
  const auto truth = load_published("a-4-fpss2");
  const SampleTable t = alternating(truth, 200, 17);
  CalibrationOptions o = one_thread();
  o.grid_max_rows = 100;    // a quarter of the 400 changes per axis: every 4th would be pitch-forward only
  o.screen_max_rows = 100;
  const CalibrationReport r = calibrate(t, o);
  EXPECT_EQ(r.yaw.residuals.points, 400u);
  EXPECT_LT(max_error(r.pitch, truth.alpha), 0.1);
  EXPECT_LT(max_error(r.yaw, truth.beta), 0.1);
}

TEST(Calibrator, OneAxisOnlyIsADataErrorNamingTheMissingAxis) {
  GridPlan plan;
  plan.yaw = false;
  SampleTable t = recording("a-4-fpss1", plan);
  t.origin = "pitch-only.csv";
  const std::string m = data_error_of(t);
  EXPECT_NE(m.find("pitch-only.csv: yaw axis (counts_beta): no offsets along yaw"), std::string::npos) << m;
  EXPECT_NE(m.find("cannot be told from this data"), std::string::npos) << m;
  plan.yaw = true;
  plan.pitch = false;
  const std::string m2 = data_error_of(recording("a-4-fpss1", plan));
  EXPECT_NE(m2.find("pitch axis (counts_alpha): no offsets along pitch"), std::string::npos) << m2;
}

TEST(Calibrator, TooFewPointsIsADataError) {
  GridPlan plan;
  plan.step_deg = 0.14;  // 3 offsets each way: 6 positions per axis for 7 coefficients
  const std::string m = data_error_of(recording("a-4-fpss1", plan));
  EXPECT_NE(m.find("too few points"), std::string::npos) << m;
  EXPECT_NE(m.find("C2..C8"), std::string::npos) << m;
}

TEST(Calibrator, MissingDwellKindsAreDataErrors) {
  const SampleTable t = recording("a-4-fpss1");
  std::string m = data_error_of(without(t, Phase::null));
  EXPECT_NE(m.find("no null dwells"), std::string::npos) << m;
  m = data_error_of(without(t, Phase::offset));
  EXPECT_NE(m.find("no offset dwells"), std::string::npos) << m;
  m = data_error_of(SampleTable{});
  EXPECT_NE(m.find("no null or offset rows"), std::string::npos) << m;
  SampleTable slews;
  slews.push_back(Sample{0, Phase::slew, 1, 10, 0, 90, 0});
  m = data_error_of(slews);
  EXPECT_NE(m.find("no null or offset rows"), std::string::npos) << m;
}

TEST(Calibrator, MethodNames) {
  EXPECT_EQ(parse_method("differences"), Method::differences);
  EXPECT_EQ(parse_method("absolute"), Method::absolute);
  EXPECT_FALSE(parse_method("relative").has_value());
  EXPECT_EQ(to_string(Method::absolute), "absolute");
}

}  // namespace
}  // namespace fpss
