// The blind check on a small seeded set covering every effect and none, and `fpss-stand diagnose`
// / `fpss-stand blindtest` end to end: files, exit codes, what cannot be told apart.
#include "stand/blindtest/blindtest.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <nlohmann/json.hpp>

#include "calib/samples.h"
#include "stand/report/diagnosis_page.h"
#include "tests/support/test_support.h"
#include "tests/support/text_order.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;

// Closing the loop: a recording with a known effect is diagnosed, the diagnosis emitted as an
// emulator bench file, the bench re-simulated from that file (load_bench_file, as `emulate
// --bench` reads it) and diagnosed again: the same cause, parameters within 5 %.
TEST(EmitBench, RoundTripThroughTheEmulatorsBenchFile) {
  const fs::path dir = fs::path(::testing::TempDir()) / "emit_bench";
  fs::create_directories(dir);
  for (const std::string spec : {"settling:amplitude_arcsec=4,tau_s=0.7", "time_skew:skew_s=0.05"}) {
    SCOPED_TRACE(spec);
    BenchConfig cfg = blindtest_bench(77);
    CoefficientSet model = cfg.truth;
    model.extra["expected_scatter_arcsec"] = expected_scatter_arcsec(cfg);
    const fs::path model_path = dir / "model.json";
    save_coefficients(model_path, model);
    cfg.effects.push_back(parse_effect(spec));
    Bench b1(cfg);
    const Diagnosis d1 = diagnose(record_session(b1, blindtest_plan()), model, blindtest_diagnosis_options());
    const std::string name = cfg.effects.front().name;
    ASSERT_EQ(d1.cause, name);
    const fs::path bench_path = dir / "bench.yaml";
    write_emitted_bench(bench_path.string(), d1, model_path.string());
    BenchConfig cfg2 = load_bench_file(bench_path);
    ASSERT_EQ(cfg2.effects.size(), 1u);
    EXPECT_EQ(cfg2.effects.front().name, name);
    EXPECT_NEAR(expected_scatter_arcsec(cfg2), expected_scatter_arcsec(cfg), 1e-9);  // the truth's scatter honoured
    cfg2.seed = 78;
    cfg2.temperature = cfg.temperature;
    Bench b2(cfg2);
    const Diagnosis d2 = diagnose(record_session(b2, blindtest_plan()), model, blindtest_diagnosis_options());
    EXPECT_EQ(d2.cause, name);
    EXPECT_EQ(d2.verdict, "explained");
    for (const auto& [k, v] : cfg.effects.front().params) {
      const double p1 = d1.causes.front().params.at(k).get<double>(), p2 = d2.causes.front().params.at(k).get<double>();
      EXPECT_NEAR(p2, p1, 0.05 * std::abs(p1)) << k;
      EXPECT_NEAR(p2, v, 0.05 * std::abs(v)) << k;
    }
  }
}

TEST(DiagnosisPage, VerdictFirstThenLimitsFiguresWithGnuplotAndTablesWithout) {
  BenchConfig cfg = blindtest_bench(111);
  cfg.effects.push_back(parse_effect("drift:pitch_arcsec_per_s=0.02,yaw_arcsec_per_s=0.01"));
  Bench bench(cfg);
  const SampleTable t = record_session(bench, blindtest_plan());
  const CoefficientSet m = cfg.truth;
  const Diagnosis d = diagnose(t, m, blindtest_diagnosis_options());
  const DiagnosisFigures f = diagnosis_figures(t, m, d, blindtest_diagnosis_options());
  ASSERT_FALSE(f.factors.empty());
  ASSERT_FALSE(f.map.empty());
  const std::string dir = ::testing::TempDir();
  auto read = [](const std::string& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  };
  const std::string with = dir + "/diag_with.html", without = dir + "/diag_without.html";
  write_diagnosis_page(with, d, f);
  const std::string h = read(with);
  // The verdict in one sentence opens the page, the detection limits follow.
  EXPECT_TRUE(test::appear_in_order(h, {"id=verdict", "id=limits", "Where the gap lies"}));
  EXPECT_NE(h.find("Explained: drift"), std::string::npos);
  if (!test::find_program("gnuplot").empty()) {
    EXPECT_NE(h.find("<svg"), std::string::npos);
    EXPECT_NE(h.find("Residual map over the field"), std::string::npos);
    EXPECT_NE(h.find("Residual against slew_rate"), std::string::npos);
  }
  const std::string saved = std::getenv("PATH") ? std::getenv("PATH") : "";
  setenv("PATH", "/nonexistent", 1);
  write_diagnosis_page(without, d, f);
  setenv("PATH", saved.c_str(), 1);
  const std::string h2 = read(without);
  EXPECT_NE(h2.find("gnuplot is not installed"), std::string::npos);
  EXPECT_EQ(h2.find("<svg"), std::string::npos);
  EXPECT_NE(h2.find("Where the gap lies"), std::string::npos);
}

TEST(BlindCheck, SeededSetCoversEveryEffectAndNoneAndMeetsTheTargets) {
  BlindTestOptions o;
  o.cases = 22;  // two shuffled blocks: every class twice
  o.seed = 2024;
  const BlindTestReport rep = run_blindtest(o);
  ASSERT_EQ(rep.cases.size(), 22u);
  std::map<std::string, int> seen;
  for (const auto& c : rep.cases) {
    ++seen[c.truth];
    SCOPED_TRACE("case " + std::to_string(c.index) + " truth " + c.truth + " diagnosed " + c.cause);
    EXPECT_TRUE(c.correct);
    if (c.truth != "none" && c.correct) {
      EXPECT_LE(c.param_error, 0.10) << c.param_errors.dump();
    }
    EXPECT_LE(c.gap_after_arcsec, 1.5 * c.noise_floor_arcsec);
    if (c.truth != "none") {
      EXPECT_GT(c.gap_before_arcsec, 3 * c.noise_floor_arcsec);  // the effect is there to find
    }
  }
  for (const auto& cls : blindtest_classes()) EXPECT_EQ(seen[cls], 2) << cls;
  EXPECT_EQ(rep.false_alarm_rate(), 0.0);
  EXPECT_GE(rep.accuracy(), 0.95);
  const auto j = rep.to_json();
  EXPECT_EQ(j["summary"]["cases"].get<size_t>(), 22u);
  EXPECT_EQ(j["confusion"]["time_skew"]["time_skew"].get<int>(), 2);
  EXPECT_NE(rep.to_text().find("confusion"), std::string::npos);
}

TEST(BlindCheck, DrawsAreSeededAndWithinTheStatedRanges) {
  const BenchConfig cfg = blindtest_bench(1);
  for (uint64_t s = 0; s < 30; ++s) {
    const auto a = draw_effects("settling", s, cfg), b = draw_effects("settling", s, cfg);
    ASSERT_EQ(a.size(), 1u);
    EXPECT_EQ(a[0].params, b[0].params);
    EXPECT_GE(a[0].params.at("tau_s"), 0.3);
    EXPECT_LE(a[0].params.at("tau_s"), 2.0);
    const auto k = draw_effects("time_skew", s, cfg);
    EXPECT_GE(k[0].params.at("skew_s"), 0.02);
    EXPECT_LE(k[0].params.at("skew_s"), 0.12);
    const auto c = draw_effects("coefficients", s, cfg);
    ASSERT_TRUE(c[0].coefficients.has_value());
    EXPECT_NE(c[0].coefficients->alpha, cfg.truth.alpha);
  }
  EXPECT_TRUE(draw_effects("none", 1, cfg).empty());
}

// ------------------------------------------------------------------ the command line

struct Result {
  int code = -1;
  std::string out, err;
};

class DiagnoseCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("fpss-diagnose-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  Result run(const std::string& args) const {
    const test::CommandResult r = test::run_stand_shell(args, dir_);
    return {r.code, r.out, r.err};
  }
  static std::string slurp(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string model() const {
    const std::string p = path("sim.json");
    save_coefficients(p, blindtest_bench(1).truth);
    return p;
  }
  std::string recording(const std::string& name, const std::vector<std::string>& effects, SessionPlan plan) const {
    BenchConfig cfg = blindtest_bench(5);
    for (const auto& e : effects) cfg.effects.push_back(parse_effect(e));
    Bench bench(cfg);
    write_samples_csv(path(name), record_session(bench, plan));
    return path(name);
  }
  static SessionPlan small_plan(bool slews) {
    SessionPlan p = blindtest_plan();
    p.grids[0].extent_deg = 0.24;
    p.grids[0].step_deg = 0.12;
    p.grids[0].samples_per_dwell = 15;
    if (!slews) p.slews.clear();
    for (auto& s : p.slews) s.amplitude_arcsec = 1000;
    return p;
  }
  static nlohmann::json read_json(const std::string& p) {
    std::ifstream in(p);
    return nlohmann::json::parse(in);
  }

  fs::path dir_;
};

TEST_F(DiagnoseCommand, FindsTheSampleTimeShiftOfContinuousSlews) {
  const std::string data = recording("real.csv", {"time_skew:skew_s=0.07"}, small_plan(true));
  const Result r = run("diagnose --model " + model() + " --data " + data + " --out " + path("gap.json") +
                       " --report " + path("gap.html") + " --settle-s 0.205");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("cause: time_skew"), std::string::npos) << r.out;
  const auto j = read_json(path("gap.json"));
  EXPECT_EQ(j["cause"], "time_skew");
  EXPECT_NEAR(j["causes"][0]["params"]["skew_s"].get<double>(), 0.07, 0.002);
  EXPECT_EQ(j["where"][0]["factor"], "slew_rate");
  EXPECT_LT(j["gap_after_arcsec"].get<double>(), 1.5 * j["noise_floor_arcsec"].get<double>());
  EXPECT_GT(j["gap_before_arcsec"].get<double>(), 10 * j["noise_floor_arcsec"].get<double>());
  EXPECT_TRUE(j["not_observable"].empty()) << j["not_observable"].dump();
  EXPECT_TRUE(fs::exists(path("gap.html")));
  EXPECT_GT(fs::file_size(path("gap.html")), 1000u);
}

TEST_F(DiagnoseCommand, RecordingWithoutSlewsSaysWhatCannotBeToldApartAndExits2) {
  const std::string data = recording("grid.csv", {"time_skew:skew_s=0.1"}, small_plan(false));
  const Result r = run("diagnose --model " + model() + " --data " + data + " --out " + path("gap.json"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("time_skew"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("motion"), std::string::npos) << r.err;
  const auto j = read_json(path("gap.json"));  // still written: what could be told is there
  EXPECT_NE(j["cause"], "time_skew");
  bool listed = false;
  for (const auto& n : j["not_observable"]) listed = listed || n["name"] == "time_skew";
  EXPECT_TRUE(listed);
  const Result partial = run("diagnose --partial --model " + model() + " --data " + data + " --out " + path("gap2.json"));
  EXPECT_EQ(partial.code, 0) << partial.err;
}

TEST_F(DiagnoseCommand, BadInputNamesTheProblemAndExits2) {
  // A model missing a key.
  const std::string bad_model = path("bad.json");
  std::ofstream(bad_model) << R"({"unit": "x", "alpha": [0, 5.3e-7, 0, 0, 0, 0, 0, 0]})";
  const std::string data = recording("real.csv", {}, small_plan(true));
  Result r = run("diagnose --model " + bad_model + " --data " + data + " --out " + path("gap.json"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("beta"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("gap.json")));
  // A single dwell.
  SessionPlan one;
  GridPlan g;
  g.extent_deg = 0;
  g.samples_per_dwell = 20;
  one.grids = {g};
  r = run("diagnose --model " + model() + " --data " + recording("one.csv", {}, one) + " --out " + path("gap.json"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("dwell"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("one.csv"), std::string::npos) << r.err;
  // Missing file.
  r = run("diagnose --model " + model() + " --data " + path("nope.csv") + " --out " + path("gap.json"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("nope.csv"), std::string::npos) << r.err;
}

TEST_F(DiagnoseCommand, BlindtestPrintsJson) {
  const Result r = run("blindtest --cases 11 --seed 3 --json --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["summary"]["cases"].get<int>(), 11);
  EXPECT_EQ(j["cases"].size(), 11u);
  EXPECT_TRUE(j.contains("confusion"));
  EXPECT_GE(j["summary"]["accuracy"].get<double>(), 0.95);
}

}  // namespace
}  // namespace fpss
