// The faulty reference: a gimbal whose pitch encoder reads 200 ppm long, calibrated without and with its certificate.
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include <nlohmann/json.hpp>

#include "base/errors.h"
#include "base/json_file.h"
#include "base/sha256.h"
#include "calib/coefficients.h"
#include "calib/reference_calibration.h"
#include "calib/samples.h"
#include "calib/transfer_function.h"
#include "fixtures/recording.h"
#include "stand/config/stand_config.h"
#include "tests/procedures/run_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

nlohmann::json value(double v, double u) { return {{"value", v}, {"u", u}}; }

// Small u, so that what is left of a 200 ppm error would show: 5 ppm, 0.5", 0.02".
nlohmann::json gimbal_errors(double pitch_scale_ppm) {
  auto axis = [](double scale_ppm) {
    return nlohmann::json{{"scale_factor_ppm", value(scale_ppm, 5)},
                          {"nonorthogonality_arcsec", value(0, 0.5)},
                          {"zero_arcsec", value(0, 0.02)},
                          {"cyclic", nlohmann::json::array()}};
  };
  return {{"certificate", "CAL-200PPM"}, {"date", "2026-02-01"}, {"lab", "test lab"},
          {"pitch", axis(pitch_scale_ppm)}, {"yaw", axis(0)}};
}

struct Outcome {
  double scale_error_ppm, edge_error_arcsec, stated_sigma_arcsec;
  nlohmann::json calibration;
};

class FaultyReference : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_.write("gimbal_errors.json", gimbal_errors(200).dump(1));
    dir_.write("bench.yaml", "gimbal_errors: gimbal_errors.json\nseed: 11\n");
    GridPlan plan;
    plan.samples_per_dwell = 20;
    const BenchConfig cfg = load_bench_file(dir_ / "bench.yaml");
    ASSERT_TRUE(cfg.gimbal_errors);
    truth_ = cfg.truth;
    write_samples_csv(dir_ / "rec.csv", simulate_null_offset(cfg, plan));
  }

  // calibrate, then the fit's pitch angle minus the truth's at the counts the truth gives +-edge:
  // the odd part is the scale error.
  Outcome calibrate(const std::string& out, const std::string& extra) {
    const auto r = test::run_stand_shell(
        "calibrate --data " + (dir_ / "rec.csv").string() + " --out " + (dir_ / out).string() + " " + extra, dir_.path());
    EXPECT_EQ(r.code, 0) << r.err;
    const nlohmann::json cal = read_json_file(dir_ / out);
    const AxisModel fit(load_coefficients(dir_ / out).alpha), truth(truth_.alpha);
    auto error_at = [&](double angle_arcsec) {
      return fit.angle_arcsec(truth.counts_for_angle(arcsec_to_rad(angle_arcsec))) - angle_arcsec;
    };
    const double e_plus = error_at(kEdge), e_minus = error_at(-kEdge);
    const double scale_arcsec = 0.5 * (e_plus - e_minus);
    return {scale_arcsec / kEdge * 1e6, std::max(std::abs(e_plus), std::abs(e_minus)),
            cal.at("uncertainties").at("pitch").at("angle_sigma_max_arcsec").get<double>(), cal};
  }

  static constexpr double kEdge = 1500;  // arcsec, inside the grid's 0.42 deg
  test::TempDir dir_{"faulty-ref"};
  CoefficientSet truth_;
};

TEST_F(FaultyReference, WithoutTheFileTheScaleIsOffWithTheFileItIsGone) {
  const Outcome without = calibrate("without.json", "");
  const Outcome with = calibrate("with.json", "--reference " + (dir_ / "gimbal_errors.json").string());
  std::cout << "pitch scale error without the reference file: " << without.scale_error_ppm << " ppm, edge error "
            << without.edge_error_arcsec << " arcsec, stated 1-sigma " << without.stated_sigma_arcsec << " arcsec\n"
            << "pitch scale error with the reference file: " << with.scale_error_ppm << " ppm, edge error "
            << with.edge_error_arcsec << " arcsec, stated 1-sigma " << with.stated_sigma_arcsec << " arcsec\n";
  // Without: the calibration inherits the encoder's 200 ppm, and its U (k = 2) does not cover it.
  EXPECT_NEAR(without.scale_error_ppm, 200, 20);
  EXPECT_GT(without.edge_error_arcsec, 2 * without.stated_sigma_arcsec);
  EXPECT_FALSE(without.calibration.contains("reference"));
  // With: gone within U, and U holds the file's u (5 ppm of the edge at least).
  EXPECT_LT(std::abs(with.scale_error_ppm), 20);
  EXPECT_LT(with.edge_error_arcsec, 2 * with.stated_sigma_arcsec);
  const double ref_u = with.calibration.at("uncertainties").at("pitch").at("reference_u_max_arcsec").get<double>();
  EXPECT_GE(ref_u, 5e-6 * kEdge);
  EXPECT_GE(with.stated_sigma_arcsec, ref_u);
  EXPECT_GT(with.stated_sigma_arcsec, without.stated_sigma_arcsec);
  const auto& block = with.calibration.at("reference");
  EXPECT_EQ(block.at("sha256"), sha256_hex(test::read_file(dir_ / "gimbal_errors.json")));
  EXPECT_EQ(block.at("certificate"), "CAL-200PPM");
  EXPECT_EQ(block.at("lab"), "test lab");
  EXPECT_EQ(block.at("date"), "2026-02-01");
  EXPECT_EQ(block.at("corrected_by"), "calibrate");
}

TEST_F(FaultyReference, ABadReferenceFileExitsTwoNamingFileAndKey) {
  nlohmann::json bad = gimbal_errors(200);
  bad["pitch"]["zero_arcsec"]["u"] = -0.1;
  const auto path = dir_.write("bad.json", bad.dump());
  const auto r = test::run_stand_shell(
      "calibrate --data " + (dir_ / "rec.csv").string() + " --out " + (dir_ / "x.json").string() + " --reference " +
          path.string(),
      dir_.path());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find(path.string()), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("pitch.zero_arcsec.u"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "x.json"));
}

TEST_F(FaultyReference, TheBenchFileNamesABadGimbalErrorsFile) {
  nlohmann::json bad = gimbal_errors(200);
  bad["yaw"].erase("cyclic");
  dir_.write("bad.json", bad.dump());
  dir_.write("bad_bench.yaml", "gimbal_errors: bad.json\n");
  const std::string m = test::error_of<InputError>([&] { load_bench_file(dir_ / "bad_bench.yaml"); });
  EXPECT_NE(m.find("bad.json"), std::string::npos) << m;
  EXPECT_NE(m.find("yaw.cyclic"), std::string::npos) << m;
}

TEST(ReferenceStandFile, ABadReferenceIsTheStandFilesErrorNamingFileAndKey) {
  test::TempDir tmp("ref-stand");
  nlohmann::json bad = gimbal_errors(200);
  bad["yaw"]["scale_factor_ppm"]["value"] = 1e5;
  tmp.write("cal.json", bad.dump());
  tmp.write("stand.yaml",
            "gimbal: {endpoint: 'modbus-tcp:127.0.0.1:1502'}\nsensor: {endpoint: 'pty:/dev/null'}\nreference: cal.json\n");
  const std::string m = test::error_of<InputError>([&] { load_stand_file(tmp / "stand.yaml"); });
  EXPECT_NE(m.find("stand.yaml:3"), std::string::npos) << m;
  EXPECT_NE(m.find((tmp / "cal.json").string()), std::string::npos) << m;
  EXPECT_NE(m.find("yaw.scale_factor_ppm.value"), std::string::npos) << m;
  tmp.write("cal.json", gimbal_errors(200).dump());
  const StandConfig ok = load_stand_file(tmp / "stand.yaml");
  ASSERT_TRUE(ok.bench.reference);
  EXPECT_EQ(ok.bench.reference->sha256, sha256_hex(test::read_file(tmp / "cal.json")));
}

// Over the wire: the stand file names the certificate, the engine corrects the reference angles,
// and the files name it.
TEST(ReferenceRun, TheEngineAppliesTheStandFilesReference) {
  test::TempDir tmp("ref-run");
  tmp.write("gimbal_errors.json", gimbal_errors(200).dump(1));
  tmp.write("bench.yaml", "gimbal_errors: gimbal_errors.json\n");
  tmp.write("stand.yaml",
            "gimbal: {endpoint: 'modbus-tcp:127.0.0.1:1'}\n"  // replaced by the emulator's
            "sensor: {endpoint: 'pty:/dev/null'}\n"
            "reference: gimbal_errors.json\n");
  const auto runs = tmp / "runs";
  const auto r = test::run_stand({"run", (test::source_dir() / "procedures" / "discrete_grid.yaml").string(), "--emulate",
                                  "--stand", (tmp / "stand.yaml").string(), "--bench", (tmp / "bench.yaml").string(),
                                  "--speed", "40", "--runs-dir", runs.string(), "--quiet"},
                                 tmp.path());
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const auto dirs = test::run_dirs(runs);
  ASSERT_EQ(dirs.size(), 1u);
  const auto run = dirs.front();
  const std::string sha = sha256_hex(test::read_file(tmp / "gimbal_errors.json"));
  const nlohmann::json doc = read_json_file(run / "run.json");
  EXPECT_EQ(doc.at("reference").at("sha256"), sha);
  EXPECT_EQ(doc.at("reference").at("certificate"), "CAL-200PPM");
  // The rows: corrected reference angles, raw encoder readings (default mount: alpha = pitch).
  const ReferenceCalibration ref = load_reference_calibration(tmp / "gimbal_errors.json");
  const SampleTable t = read_samples_csv(run / "samples.csv");
  const auto gp = t.numeric_column("gimbal_pitch_arcsec"), gy = t.numeric_column("gimbal_yaw_arcsec");
  double largest_correction = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    const auto [p, y] = ref.true_from_reading(gp[i], gy[i]);
    ASSERT_NEAR(t.ref_pitch_arcsec[i], p, 1e-9) << i;
    ASSERT_NEAR(t.ref_yaw_arcsec[i], y, 1e-9) << i;
    largest_correction = std::max(largest_correction, std::abs(gp[i] - p));
  }
  EXPECT_GT(largest_correction, 0.2);  // 200 ppm of the grid's edge
  const nlohmann::json cal = read_json_file(run / "calibration.json");
  EXPECT_EQ(cal.at("reference").at("sha256"), sha);
  EXPECT_EQ(cal.at("reference").at("corrected_by"), "run");
  // The fit is the truth, within its stated U.
  const AxisModel fit(load_coefficients(run / "calibration.json").alpha), truth(load_published("a-6-fpss1").alpha);
  const double sigma = cal.at("uncertainties").at("pitch").at("angle_sigma_max_arcsec").get<double>();
  for (double a : {-1500.0, 1500.0}) {
    EXPECT_LT(std::abs(fit.angle_arcsec(truth.counts_for_angle(arcsec_to_rad(a))) - a), 2 * sigma) << a;
  }
  // Offline on the corrected recording: the same file adds its u only; another is refused.
  const auto again = test::run_stand_shell("calibrate --data " + (run / "samples.csv").string() + " --out " +
                                               (tmp / "again.json").string() + " --reference " +
                                               (tmp / "gimbal_errors.json").string(),
                                           tmp.path());
  ASSERT_EQ(again.code, 0) << again.err;
  EXPECT_EQ(read_json_file(tmp / "again.json").at("reference").at("corrected_by"), "run");
  tmp.write("other.json", gimbal_errors(0).dump(1));
  const auto other = test::run_stand_shell("calibrate --data " + (run / "samples.csv").string() + " --out " +
                                               (tmp / "other_cal.json").string() + " --reference " +
                                               (tmp / "other.json").string(),
                                           tmp.path());
  EXPECT_EQ(other.code, 2) << other.err;
  EXPECT_NE(other.err.find("already corrected"), std::string::npos) << other.err;
}

}  // namespace
}  // namespace fpss
