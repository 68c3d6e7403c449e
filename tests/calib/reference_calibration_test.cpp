// The reference calibration file: its strict reader, the error model, its inverse and the propagated u.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <nlohmann/json.hpp>

#include "base/errors.h"
#include "base/sha256.h"
#include "calib/reference_calibration.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

nlohmann::json value(double v, double u) { return {{"value", v}, {"u", u}}; }

nlohmann::json axis(double scale_ppm, double nonorth, double zero, nlohmann::json cyclic = nlohmann::json::array()) {
  return {{"scale_factor_ppm", value(scale_ppm, 20)},
          {"nonorthogonality_arcsec", value(nonorth, 2)},
          {"zero_arcsec", value(zero, 1)},
          {"cyclic", cyclic}};
}

nlohmann::json example() {
  const nlohmann::json cyc = nlohmann::json::array(
      {{{"harmonic", 1}, {"amplitude_arcsec", value(3.0, 0.2)}, {"phase_rad", value(0.4, 0.05)}},
       {{"harmonic", 36}, {"amplitude_arcsec", value(0.8, 0.1)}, {"phase_rad", value(-1.0, 0.1)}}});
  return {{"certificate", "CAL-1"}, {"date", "2026-01-15"}, {"lab", "lab"},
          {"pitch", axis(200, 5, -2, cyc)}, {"yaw", axis(-150, -8, 3)}};
}

std::string error_of(const nlohmann::json& j) {
  return test::error_of<InputError>([&] { parse_reference_calibration(j, "ref.json"); });
}

TEST(ReferenceCalibration, ReadsTheExampleFileAndNamesItsBytes) {
  const auto path = test::source_dir() / "procedures" / "reference_example.json";
  const ReferenceCalibration r = load_reference_calibration(path);
  EXPECT_EQ(r.sha256, sha256_hex(test::read_file(path)));
  EXPECT_EQ(r.certificate, "EXAMPLE-0000");
  EXPECT_EQ(r.pitch.scale_factor_ppm.u, 20);
  EXPECT_EQ(r.yaw.nonorthogonality_arcsec.u, 2);
  EXPECT_EQ(r.pitch.zero_arcsec.u, 1);
  EXPECT_EQ(r.identity().at("sha256"), r.sha256);
  // Zero errors: the map is the identity.
  const auto [p, y] = r.true_from_reading(1234.5, -987.25);
  EXPECT_DOUBLE_EQ(p, 1234.5);
  EXPECT_DOUBLE_EQ(y, -987.25);
}

TEST(ReferenceCalibration, TheErrorModelIsReadingMinusTrue) {
  nlohmann::json j = example();
  j["pitch"]["cyclic"] = nlohmann::json::array();
  const ReferenceCalibration r = parse_reference_calibration(j, "ref.json");
  const auto [rp, ry] = r.reading_from_true(3600, 1800);
  // pitch: zero -2, +200 ppm of 3600, sin(5") of yaw 1800.
  EXPECT_NEAR(rp - 3600, -2 + 200e-6 * 3600 + std::sin(5 / 206264.806) * 1800, 1e-9);
  // yaw: zero +3, -150 ppm of 1800, sin(-8") of pitch 3600.
  EXPECT_NEAR(ry - 1800, 3 - 150e-6 * 1800 + std::sin(-8 / 206264.806) * 3600, 1e-9);
}

TEST(ReferenceCalibration, TheInverseUndoesTheErrorsTo1e9Arcsec) {
  const ReferenceCalibration r = parse_reference_calibration(example(), "ref.json");
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> angle(-7200, 7200);
  for (int i = 0; i < 2000; ++i) {
    const double p = angle(rng), y = angle(rng);
    const auto [rp, ry] = r.reading_from_true(p, y);
    const auto [tp, ty] = r.true_from_reading(rp, ry);
    ASSERT_NEAR(tp, p, 1e-9) << p << " " << y;
    ASSERT_NEAR(ty, y, 1e-9) << p << " " << y;
  }
}

TEST(ReferenceCalibration, UncertaintyGrowsWithAngleByEachTermsU) {
  nlohmann::json j = example();
  j["pitch"]["cyclic"] = nlohmann::json::array();
  const ReferenceCalibration r = parse_reference_calibration(j, "ref.json");
  // At the origin only the zero's u is left.
  EXPECT_NEAR(r.u_true_arcsec(0, 0).first, 1.0, 1e-12);
  // At 7200" pitch, yaw 0: zero 1" and 20 ppm of 7200" = 0.144" in quadrature.
  EXPECT_NEAR(r.u_true_arcsec(7200, 0).first, std::hypot(1.0, 20e-6 * 7200), 1e-9);
  // The yaw axis leans by its nonorthogonality (u 2") on the pitch angle.
  EXPECT_NEAR(r.u_true_arcsec(7200, 0).second, std::hypot(1.0, 2 / 206264.806 * 7200), 1e-6);
}

TEST(ReferenceCalibration, StrictReaderNamesTheFileAndTheKey) {
  auto with = [](auto edit) {
    nlohmann::json j = example();
    edit(j);
    return error_of(j);
  };
  struct Case {
    std::function<void(nlohmann::json&)> edit;
    std::string want;
  };
  const std::vector<Case> cases = {
      {[](auto& j) { j.erase("lab"); }, "key \"lab\": missing"},
      {[](auto& j) { j["extra"] = 1; }, "key \"extra\": unknown key"},
      {[](auto& j) { j["pitch"]["scale_factor_ppm"]["value"] = 20000; }, "key \"pitch.scale_factor_ppm.value\": 20000 is outside"},
      {[](auto& j) { j["yaw"]["zero_arcsec"]["u"] = -1; }, "key \"yaw.zero_arcsec.u\": -1 is outside"},
      {[](auto& j) { j["yaw"]["nonorthogonality_arcsec"].erase("u"); }, "key \"yaw.nonorthogonality_arcsec.u\": missing"},
      {[](auto& j) { j["pitch"]["zero_arcsec"]["value"] = "1"; }, "key \"pitch.zero_arcsec.value\": expected a number"},
      {[](auto& j) { j["pitch"]["cyclic"][1]["harmonic"] = 65; }, "key \"pitch.cyclic[1].harmonic\": 65 is outside"},
      {[](auto& j) { j["pitch"]["cyclic"][0]["harmonic"] = 1.5; }, "key \"pitch.cyclic[0].harmonic\": expected a whole"},
      {[](auto& j) { j["pitch"]["cyclic"][0]["phase_rad"]["value"] = 7; }, "key \"pitch.cyclic[0].phase_rad.value\""},
      {[](auto& j) { j["pitch"]["cyclic"][0]["width"] = 7; }, "key \"pitch.cyclic[0].width\": unknown key"},
      {[](auto& j) { j["yaw"]["cyclic"] = nlohmann::json::array(); for (int i = 0; i < 17; ++i) j["yaw"]["cyclic"].push_back(j["pitch"]["cyclic"][0]); },
       "key \"yaw.cyclic\": 17 terms; at most 16"},
      {[](auto& j) { j["pitch"] = 3; }, "key \"pitch\": expected an object"},
  };
  for (const Case& c : cases) {
    const std::string m = with(c.edit);
    EXPECT_NE(m.find("ref.json: "), std::string::npos) << m;
    EXPECT_NE(m.find(c.want), std::string::npos) << m;
  }
}

TEST(ReferenceCalibration, NonFiniteNumbersInTheFileAreRefused) {
  test::TempDir dir("refcal");
  std::string text = example().dump();
  text.replace(text.find("\"value\":200"), 11, "\"value\":1e400");
  const auto path = dir.write("ref.json", text);
  const std::string m = test::error_of<InputError>([&] { load_reference_calibration(path); });
  EXPECT_NE(m.find(path.string()), std::string::npos) << m;
}

}  // namespace
}  // namespace fpss
