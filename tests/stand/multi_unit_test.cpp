// Several units on one gimbal in one pass (`run --emulate --bench` with sensors:): each unit's fit,
// how the units sit relative to each other, a unit lost mid-run, a wrong serial, a gimbal fault.
#include <gtest/gtest.h>

#include <cmath>
#include <csignal>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/json_file.h"
#include "calib/calibrator.h"
#include "calib/coefficients.h"
#include "calib/transfer_function.h"
#include "calib/units.h"
#include "tests/procedures/run_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;

std::string published(const std::string& name) {
  return (test::source_dir() / "calib" / "data" / "published" / (name + ".json")).string();
}

// One sensors: entry of a bench file.
struct BenchUnit {
  std::string serial, truth, effects = "[]";
};

std::string bench_yaml(const std::vector<BenchUnit>& units, const std::string& stand_effects = "") {
  std::string y = "seed: 5\n";
  if (!stand_effects.empty()) y += "effects: " + stand_effects + "\n";
  y += "sensors:\n";
  for (const auto& u : units) {
    y += "  - serial: " + u.serial + "\n    truth: " + published(u.truth) +
         "\n    mount: {alpha: +pitch, beta: +yaw}\n    effects: " + u.effects + "\n";
  }
  return y;
}

// The fit's largest distance from the truth over +-0.4 deg (the counts the truth gives there).
double error_over_04deg(const AxisCoeffs& fit, const AxisCoeffs& truth) {
  const AxisModel t(truth);
  const double a = t.counts_for_angle(arcsec_to_rad(-1440)), b = t.counts_for_angle(arcsec_to_rad(1440));
  return compare_transfer(fit, truth, std::min(a, b), std::max(a, b)).max_abs_arcsec;
}

class MultiUnit : public ::testing::Test {
 protected:
  test::CommandResult run(const std::string& bench, const std::vector<std::string>& extra = {}) {
    const fs::path b = dir_.write("bench.yaml", bench);
    std::vector<std::string> args{"run", (test::source_dir() / "procedures" / "discrete_grid.yaml").string(), "--emulate",
                                  "--bench", b.string(), "--speed", "50", "--runs-dir", (dir_ / "runs").string()};
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = test::run_stand(args, dir_.path(), "run", 300);
    const auto dirs = test::run_dirs(dir_ / "runs");
    if (!dirs.empty()) run_dir_ = dirs.back();
    return r;
  }
  nlohmann::json run_json() const { return read_json_file(run_dir_ / "run.json"); }
  fs::path unit_dir(const std::string& serial) const { return run_dir_ / "units" / serial; }
  void expect_fit_near_truth(const std::string& serial, const std::string& truth) {
    SCOPED_TRACE(serial);
    const CoefficientSet fit = load_coefficients(unit_dir(serial) / "calibration.json");
    const CoefficientSet t = load_published(truth);
    EXPECT_LT(error_over_04deg(fit.alpha, t.alpha), 0.1);
    EXPECT_LT(error_over_04deg(fit.beta, t.beta), 0.1);
  }

  test::TempDir dir_{"multi-unit"};
  fs::path run_dir_;
};

TEST_F(MultiUnit, TwoUnitsOfThePaperInOnePassEachWithinATenthOfItsTruth) {
  const auto r = test::run_stand({"run", (test::source_dir() / "procedures" / "discrete_grid.yaml").string(), "--emulate",
                                  "--bench", (test::source_dir() / "procedures" / "two_unit_bench.yaml").string(),
                                  "--speed", "50", "--runs-dir", (dir_ / "runs").string()},
                                 dir_.path(), "run", 300);
  ASSERT_EQ(r.code, 0) << r.err;
  run_dir_ = test::run_dirs(dir_ / "runs").back();
  expect_fit_near_truth("FPSS1-A6", "a-6-fpss1");
  expect_fit_near_truth("FPSS2-A6", "a-6-fpss2");
  const nlohmann::json j = run_json();
  EXPECT_EQ(j.at("points").at("total"), 113);
  EXPECT_EQ(j.at("files").at("samples"), "units/FPSS1-A6/samples.csv");
  ASSERT_EQ(j.at("units").size(), 2u);
  for (const auto& u : j.at("units")) EXPECT_EQ(u.at("outcome"), "completed") << u.dump();
  // Every point recorded for both units against the same gimbal readings.
  const SampleTable a = read_samples_csv(unit_dir("FPSS1-A6") / "samples.csv");
  const SampleTable b = read_samples_csv(unit_dir("FPSS2-A6") / "samples.csv");
  ASSERT_FALSE(a.empty());
  EXPECT_EQ(a.step.back(), b.step.back());
  const auto ga = a.numeric_column("gimbal_time_s"), gb = b.numeric_column("gimbal_time_s");
  std::set<double> readings_a(ga.begin(), ga.end()), readings_b(gb.begin(), gb.end());
  size_t shared = 0;
  for (double t : readings_b) shared += readings_a.count(t);
  EXPECT_GT(static_cast<double>(shared), 0.95 * static_cast<double>(readings_b.size()));
  // FPSS2's null relative to FPSS1's: the truths' difference, within the stated sigma.
  const auto& rel = j.at("units").at(1).at("relative");
  EXPECT_EQ(rel.at("to"), "FPSS1-A6");
  const CoefficientSet t1 = load_published("a-6-fpss1"), t2 = load_published("a-6-fpss2");
  const double want_p = AxisModel(t2.alpha).angle_arcsec(0) - AxisModel(t1.alpha).angle_arcsec(0);
  const double want_y = AxisModel(t2.beta).angle_arcsec(0) - AxisModel(t1.beta).angle_arcsec(0);
  EXPECT_NEAR(rel.at("boresight_pitch_arcsec").get<double>(), want_p, 4 * rel.at("boresight_pitch_sigma_arcsec").get<double>());
  EXPECT_NEAR(rel.at("boresight_yaw_arcsec").get<double>(), want_y, 4 * rel.at("boresight_yaw_sigma_arcsec").get<double>());
  EXPECT_LT(std::abs(rel.at("roll_arcsec").get<double>()), 4 * rel.at("roll_sigma_arcsec").get<double>());
  // One page, a banner per unit; each unit's own report beside its calibration.
  const std::string page = test::read_file(run_dir_ / "report.html");
  EXPECT_NE(page.find("id=\"verdict-FPSS1-A6\""), std::string::npos);
  EXPECT_NE(page.find("id=\"verdict-FPSS2-A6\""), std::string::npos);
  EXPECT_TRUE(fs::exists(unit_dir("FPSS2-A6") / "report.html"));
  EXPECT_FALSE(fs::exists(run_dir_ / "samples.csv"));
}

// Each unit on a clock of its own (clock.sync: host, as a real stand's lines): the followers' frames
// are taken by their receipt and the fits hold as well.
TEST_F(MultiUnit, OnHostClocksEachUnitIsWithinATenthOfItsTruth) {
  const fs::path stand = dir_.write("host.yaml",
                                    "gimbal: {endpoint: \"modbus-tcp:127.0.0.1:1\"}\n"
                                    "clock: {sync: host}\n"
                                    "sensors:\n"
                                    "  - {unit: U1, endpoint: \"pty:/nonexistent/1\"}\n"
                                    "  - {unit: U2, endpoint: \"pty:/nonexistent/2\"}\n");
  const auto r = run(bench_yaml({{"U1", "a-6-fpss1"}, {"U2", "a-5-fpss2"}}), {"--stand", stand.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  expect_fit_near_truth("U1", "a-6-fpss1");
  expect_fit_near_truth("U2", "a-5-fpss2");
}

// Each unit its own sensor options: unit 2 streams at twice the lead's rate, with its own frame
// timeout and clock offset; the lead's rate paces the dwells, unit 2's dwells hold about twice the
// frames over the same dwells, and both fits hold.
TEST_F(MultiUnit, EachUnitStreamsAtItsOwnRate) {
  const fs::path stand = dir_.write("rates.yaml",
                                    "gimbal: {endpoint: \"modbus-tcp:127.0.0.1:1\"}\n"
                                    "sensors:\n"
                                    "  - {unit: U1, endpoint: \"pty:/nonexistent/1\", sample_rate_hz: 50}\n"
                                    "  - {unit: U2, endpoint: \"pty:/nonexistent/2\", sample_rate_hz: 100,"
                                    " frame_timeout_s: 0.5, sensor_offset_s: 0}\n");
  const auto r = run(bench_yaml({{"U1", "a-6-fpss1"}, {"U2", "a-5-fpss2"}}), {"--stand", stand.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  expect_fit_near_truth("U1", "a-6-fpss1");
  expect_fit_near_truth("U2", "a-5-fpss2");
  const SampleTable a = read_samples_csv(unit_dir("U1") / "samples.csv");
  const SampleTable b = read_samples_csv(unit_dir("U2") / "samples.csv");
  ASSERT_FALSE(a.empty());
  EXPECT_EQ(a.step.back(), b.step.back());
  const double ratio = static_cast<double>(b.size()) / static_cast<double>(a.size());
  EXPECT_GT(ratio, 1.8);
  EXPECT_LT(ratio, 2.2);
}

TEST_F(MultiUnit, FourUnitsOfDifferentTruthsAndARolledBiasedOne) {
  const auto r = run(bench_yaml({{"U1", "a-6-fpss1"},
                                 {"U2", "a-6-fpss2"},
                                 {"U3", "a-5-fpss1"},
                                 {"U4", "a-4-fpss2",
                                  "[{name: boresight_roll, roll_arcsec: 60}, {name: bias, pitch_arcsec: 0, yaw_arcsec: 5}]"}}));
  ASSERT_EQ(r.code, 0) << r.err;
  expect_fit_near_truth("U1", "a-6-fpss1");
  expect_fit_near_truth("U2", "a-6-fpss2");
  expect_fit_near_truth("U3", "a-5-fpss1");
  const nlohmann::json j = run_json();
  ASSERT_EQ(j.at("units").size(), 4u);
  const auto& rel = j.at("units").at(3).at("relative");
  EXPECT_NEAR(rel.at("roll_arcsec").get<double>(), 60.0, 4 * rel.at("roll_sigma_arcsec").get<double>());
  EXPECT_LT(rel.at("roll_sigma_arcsec").get<double>(), 5.0);
  // The bias moves U4's null by -5 arcsec in yaw (the Sun reads 5 arcsec further on).
  const CoefficientSet t1 = load_published("a-6-fpss1"), t4 = load_published("a-4-fpss2");
  const double want_y = AxisModel(t4.beta).angle_arcsec(0) - AxisModel(t1.beta).angle_arcsec(0) - 5.0;
  EXPECT_NEAR(rel.at("boresight_yaw_arcsec").get<double>(), want_y, 0.5);
  for (const char* u : {"U2", "U3"}) {
    EXPECT_LT(std::abs(j.at("units").at(u[1] - '1').at("relative").at("roll_arcsec").get<double>()), 5.0) << u;
  }
}

TEST_F(MultiUnit, AUnitUnpluggedMidRunIsLostAndTheOthersComplete) {
  const auto r = run(bench_yaml({{"U1", "a-6-fpss1"}, {"U2", "a-6-fpss2"}, {"U3", "a-5-fpss1"}}),
                     {"--fault", "sensor_silence:duration_s=100000,at_s=60,unit=2"});
  EXPECT_EQ(r.code, 1) << r.err;  // not every unit completed
  const nlohmann::json j = run_json();
  EXPECT_EQ(j.at("outcome"), "completed");
  const auto& lost = j.at("units").at(1);
  EXPECT_EQ(lost.at("outcome"), "lost");
  EXPECT_EQ(lost.at("loss_cause"), "silence");
  EXPECT_GT(lost.at("lost_at_point").get<int64_t>(), 1);
  EXPECT_FALSE(lost.contains("calibration"));
  EXPECT_EQ(j.at("units").at(0).at("outcome"), "completed");
  EXPECT_EQ(j.at("units").at(2).at("outcome"), "completed");
  expect_fit_near_truth("U1", "a-6-fpss1");
  expect_fit_near_truth("U3", "a-5-fpss1");
  const std::string page = test::read_file(run_dir_ / "report.html");
  EXPECT_NE(page.find("unit U2 lost (silence)"), std::string::npos);
}

TEST_F(MultiUnit, TheLeadUnitLostHandsOverAndTheRestComplete) {
  const auto r = run(bench_yaml({{"U1", "a-6-fpss1"}, {"U2", "a-6-fpss2"}}),
                     {"--fault", "sensor_silence:duration_s=100000,at_s=40,unit=1"});
  EXPECT_EQ(r.code, 1) << r.err;
  const nlohmann::json j = run_json();
  EXPECT_EQ(j.at("outcome"), "completed");
  EXPECT_EQ(j.at("units").at(0).at("outcome"), "lost");
  EXPECT_EQ(j.at("units").at(1).at("outcome"), "completed");
  expect_fit_near_truth("U2", "a-6-fpss2");
}

TEST_F(MultiUnit, AWrongSerialIsLostBeforeTheRunAndAGimbalFaultStopsEveryUnit) {
  const fs::path stand = dir_.write("stand.yaml",
                                    "gimbal: {endpoint: \"modbus-tcp:127.0.0.1:1\"}\n"
                                    "sensors:\n"
                                    "  - {unit: U1, endpoint: \"pty:/nonexistent/1\", axes: {pitch: alpha, yaw: beta}}\n"
                                    "  - {unit: NOT-U2, endpoint: \"pty:/nonexistent/2\", axes: {pitch: alpha, yaw: beta}}\n");
  auto r = run(bench_yaml({{"U1", "a-6-fpss1"}, {"U2", "a-6-fpss2"}}), {"--stand", stand.string()});
  EXPECT_EQ(r.code, 1) << r.err;
  nlohmann::json j = run_json();
  EXPECT_EQ(j.at("units").at(1).at("outcome"), "lost");
  EXPECT_EQ(j.at("units").at(1).at("loss_cause"), "wrong_serial");
  EXPECT_EQ(j.at("units").at(0).at("outcome"), "completed");
  expect_fit_near_truth("U1", "a-6-fpss1");

  // No re-measurement: the fault ends the run, for every unit at once.
  const fs::path strict = dir_.write("strict.yaml",
                                     "gimbal: {endpoint: \"modbus-tcp:127.0.0.1:1\"}\n"
                                     "points: {max_remeasure: 0}\n"
                                     "sensors:\n"
                                     "  - {unit: U1, endpoint: \"pty:/nonexistent/1\", axes: {pitch: alpha, yaw: beta}}\n"
                                     "  - {unit: U2, endpoint: \"pty:/nonexistent/2\", axes: {pitch: alpha, yaw: beta}}\n");
  r = run(bench_yaml({{"U1", "a-6-fpss1"}, {"U2", "a-6-fpss2"}}),
          {"--stand", strict.string(), "--fault", "gimbal_fault:code=1,at_s=30"});
  EXPECT_EQ(r.code, 1) << r.err;
  j = run_json();
  EXPECT_EQ(j.at("outcome"), "failed");
  for (const auto& u : j.at("units")) EXPECT_EQ(u.at("outcome"), "failed") << u.dump();
}

// Stand or unit: a stand backlash of 3 arcsec and a bias on U2 only. The run's own diagnose step
// (models: by serial) and `diagnose --run` both name the backlash the stand's and the bias U2's.
TEST_F(MultiUnit, TheStandsBacklashAndOneUnitsBiasAreToldApart) {
  std::string procedure = test::read_file(test::source_dir() / "procedures" / "sim_to_real.yaml");
  const auto at = procedure.find("  - diagnose:");
  ASSERT_NE(at, std::string::npos);
  procedure = procedure.substr(0, at) + "  - diagnose:\n      partial: true\n      models:\n        U1: " +
              published("a-6-fpss1") + "\n        U2: " + published("a-6-fpss2") + "\n";
  const fs::path proc = dir_.write("sim_to_real_units.yaml", procedure);
  const fs::path bench = dir_.write(
      "bench.yaml", bench_yaml({{"U1", "a-6-fpss1"}, {"U2", "a-6-fpss2", "[{name: bias, pitch_arcsec: 2, yaw_arcsec: -1.5}]"}},
                               "[{name: backlash, width_arcsec: 3}]"));
  const auto r = test::run_stand({"run", proc.string(), "--emulate", "--bench", bench.string(), "--speed", "100",
                                  "--runs-dir", (dir_ / "runs").string()},
                                 dir_.path(), "run", 300);
  ASSERT_EQ(r.code, 0) << r.err;
  run_dir_ = test::run_dirs(dir_ / "runs").back();
  auto check = [](const nlohmann::json& j) {
    ASSERT_EQ(j.at("stand_effects").size(), 1u) << j.dump(1);
    EXPECT_EQ(j.at("stand_effects").at(0).at("name"), "backlash");
    EXPECT_NEAR(j.at("stand_effects").at(0).at("params").at("width_arcsec").get<double>(), 3.0, 0.3);
    EXPECT_TRUE(j.at("unit_effects").at("U1").empty()) << j.dump(1);
    ASSERT_EQ(j.at("unit_effects").at("U2").size(), 1u) << j.dump(1);
    EXPECT_EQ(j.at("unit_effects").at("U2").at(0).at("name"), "bias");
    EXPECT_NEAR(j.at("unit_effects").at("U2").at(0).at("params").at("pitch_arcsec").get<double>(), 2.0, 0.2);
  };
  check(read_json_file(run_dir_ / "GAP.json"));
  EXPECT_TRUE(fs::exists(unit_dir("U1") / "GAP.json"));
  EXPECT_TRUE(fs::exists(unit_dir("U2") / "GAP.html"));
  const auto d = test::run_stand({"diagnose", "--run", run_dir_.string(), "--model", "U1=" + published("a-6-fpss1"),
                                  "--model", "U2=" + published("a-6-fpss2"), "--out", (dir_ / "joint.json").string(),
                                  "--partial"},
                                 dir_.path(), "diagnose", 300);
  ASSERT_EQ(d.code, 0) << d.err;
  check(read_json_file(dir_ / "joint.json"));
  // A unit the run does not have, and a pair without its serial: exit 2, naming them.
  auto bad = test::run_stand({"diagnose", "--run", run_dir_.string(), "--model", "U9=" + published("a-6-fpss1"), "--out",
                              (dir_ / "bad.json").string()},
                             dir_.path(), "bad", 60);
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("no unit U9 (it has U1, U2)"), std::string::npos) << bad.err;
  bad = test::run_stand({"diagnose", "--run", run_dir_.string(), "--model", published("a-6-fpss1"), "--out",
                         (dir_ / "bad.json").string()},
                        dir_.path(), "bad2", 60);
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("SERIAL=FILE"), std::string::npos) << bad.err;
}

// Interrupted and resumed: each unit's file cut back to the journal and continued, none repeated.
TEST_F(MultiUnit, AnInterruptedRunOfTwoUnitsResumes) {
  const fs::path runs = dir_ / "runs";
  test::Child c = test::start_stand({"run", (test::source_dir() / "procedures" / "discrete_grid.yaml").string(), "--emulate",
                                     "--bench", (test::source_dir() / "procedures" / "two_unit_bench.yaml").string(),
                                     "--runs-dir", runs.string(), "--quiet"},
                                    dir_.path());
  ASSERT_TRUE(test::wait_until([&] { return test::journaled_points(runs) >= 10; }, 60, std::chrono::milliseconds(20)));
  c.signal(SIGINT);
  EXPECT_EQ(c.wait(60), 1);
  run_dir_ = test::run_dirs(runs).back();
  EXPECT_EQ(run_json().at("outcome"), "interrupted");
  const auto r = test::run_stand({"run", "--resume", run_dir_.string(), "--quiet"}, dir_.path(), "resume", 300);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(run_json().at("outcome"), "completed");
  for (const char* u : {"FPSS1-A6", "FPSS2-A6"}) {
    SCOPED_TRACE(u);
    const SampleTable t = read_samples_csv(unit_dir(u) / "samples.csv");
    std::set<int64_t> steps(t.step.begin(), t.step.end());
    EXPECT_EQ(steps.size(), 113u);
    for (size_t i = 1; i < t.size(); ++i) ASSERT_GE(t.step[i], t.step[i - 1]) << "row " << i;
    expect_fit_near_truth(u, std::string("a-6-fpss") + u[4]);
  }
}

// accept with two units: a verdict, certificate and catalogue record per unit, one run id.
TEST_F(MultiUnit, AcceptCertifiesEachUnitUnderItsSerial) {
  const auto r = test::run_stand({"accept", "--emulate", "--bench", (test::source_dir() / "procedures" / "two_unit_bench.yaml").string(),
                                  "--speed", "50", "--runs-dir", (dir_ / "runs").string(), "--quiet", "--no-progress"},
                                 dir_.path(), "accept", 300);
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  run_dir_ = test::run_dirs(dir_ / "runs").back();
  const nlohmann::json j = run_json();
  for (const char* u : {"FPSS1-A6", "FPSS2-A6"}) {
    SCOPED_TRACE(u);
    EXPECT_TRUE(fs::exists(unit_dir(u) / "certificate.txt"));
    const nlohmann::json acc = read_json_file(unit_dir(u) / "acceptance.json");
    EXPECT_EQ(acc.at("unit"), u);
  }
  for (const auto& u : j.at("units")) EXPECT_EQ(u.at("verdict"), "pass") << u.dump();
  const auto h = test::run_stand({"history", "FPSS2-A6", "--runs-dir", (dir_ / "runs").string()}, dir_.path(), "history", 60);
  EXPECT_EQ(h.code, 0) << h.err;
  EXPECT_NE(h.out.find(j.at("run_id").get<std::string>().substr(0, 8)), std::string::npos) << h.out;
  // runs --unit finds the run under either serial, with its units' verdict.
  const auto runs = test::run_stand({"runs", "--unit", "FPSS2-A6", "--runs-dir", (dir_ / "runs").string(), "--json"},
                                    dir_.path(), "runs", 60);
  ASSERT_EQ(runs.code, 0) << runs.err;
  const nlohmann::json rj = nlohmann::json::parse(runs.out);
  ASSERT_EQ(rj.size(), 1u) << runs.out;
  EXPECT_EQ(rj.at(0).at("verdict"), "pass");
  // show lists the units; a catalogue rebuilt from the folders has each unit's calibration and acceptance.
  const auto show = test::run_stand({"show", run_dir_.string(), "--json"}, dir_.path(), "show", 60);
  ASSERT_EQ(show.code, 0) << show.err;
  const nlohmann::json sj = nlohmann::json::parse(show.out);
  EXPECT_EQ(sj.at("verdict"), "pass");
  ASSERT_EQ(sj.at("units").size(), 2u);
  EXPECT_EQ(sj.at("units").at(1).at("verdict"), "pass");
  fs::remove(dir_ / "runs" / "stand.db");
  const auto rb = test::run_stand({"catalogue", "rebuild", "--runs-dir", (dir_ / "runs").string()}, dir_.path(), "rebuild", 60);
  ASSERT_EQ(rb.code, 0) << rb.err;
  EXPECT_NE(rb.out.find("2 calibrations, 2 acceptances"), std::string::npos) << rb.out;
}

}  // namespace
}  // namespace fpss
