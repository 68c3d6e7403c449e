// Coefficient files: the 14 published sets, round trips, and every way a file can be wrong.
#include "calib/coefficients.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>

#include "base/errors.h"
#include "base/text_file.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;

using test::TempDir;

const std::string kGood8 = "[1e-4, 5e-7, 3e-5, 3e-4, 3.4, -1e-4, 1e-4, 1.7]";

TEST(Coefficients, FourteenPublishedSetsThreeFlagged) {
  const auto names = published_names();
  ASSERT_EQ(names.size(), 14u);
  EXPECT_EQ(names.front(), "a-1-fpss1");
  EXPECT_EQ(names.back(), "a-7-fpss2");
  std::vector<std::string> suspect;
  for (const auto& n : names) {
    if (is_suspect(load_published(n))) suspect.push_back(n);
  }
  EXPECT_EQ(suspect, (std::vector<std::string>{"a-1-fpss1", "a-3-fpss2", "a-7-fpss1"}));
  // Figures as printed: Table A-7 FPSS1 B7 and Table A-2 FPSS2 A1.
  EXPECT_DOUBLE_EQ(load_published("a-7-fpss1").beta[6], 0.1877559e-5);
  EXPECT_DOUBLE_EQ(load_published("a-2-fpss2").alpha[0], 0.8337881e-3);
  EXPECT_EQ(load_published("a-2-fpss2").unit, "FPSS2");
}

TEST(Coefficients, SaveLoadRoundTripKeepsExtraKeys) {
  TempDir d;
  CoefficientSet s = load_published("a-5-fpss2");
  s.extra["residuals"] = {{"pitch", {{"points", 12}}}};
  const auto p = d.path() / "out.json";
  save_coefficients(p, s);
  EXPECT_FALSE(fs::exists(p.string() + ".tmp"));
  const CoefficientSet r = load_coefficients(p);
  EXPECT_EQ(r.unit, s.unit);
  EXPECT_EQ(r.alpha, s.alpha);  // bit-exact: JSON numbers are written shortest round-trip
  EXPECT_EQ(r.beta, s.beta);
  EXPECT_EQ(r.extra, s.extra);
}

TEST(Coefficients, BadFilesNameTheFileAndKey) {
  TempDir d;
  const std::string good8 = "[1,2,3,4,5,6,7,8]";
  auto msg = [&](const std::string& name, const std::string& text) {
    const auto p = d.write(name, text);
    return test::error_of<InputError>([&] { load_coefficients(p); });
  };
  std::string m = msg("missing.json", R"({"unit": "X", "alpha": )" + good8 + "}");
  EXPECT_NE(m.find("missing.json"), std::string::npos) << m;
  EXPECT_NE(m.find("missing key \"beta\""), std::string::npos) << m;

  m = msg("short.json", R"({"alpha": [1,2,3,4,5,6,7], "beta": )" + good8 + "}");
  EXPECT_NE(m.find("\"alpha\" must be an array of 8 numbers"), std::string::npos) << m;

  m = msg("long.json", R"({"alpha": )" + good8 + R"(, "beta": [1,2,3,4,5,6,7,8,9]})");
  EXPECT_NE(m.find("\"beta\" must be an array of 8"), std::string::npos) << m;

  m = msg("string.json", R"({"alpha": [1,2,3,"x",5,6,7,8], "beta": )" + good8 + "}");
  EXPECT_NE(m.find("\"alpha\"[3] (C4) must be a finite number"), std::string::npos) << m;

  m = msg("overflow.json", R"({"alpha": )" + good8 + R"(, "beta": [1,2,3,4,5,6,7,1e999]})");
  EXPECT_NE(m.find("overflow.json:1:58: not valid JSON"), std::string::npos) << m;
  EXPECT_NE(m.find("number overflow"), std::string::npos) << m;

  m = msg("bad.json", R"({"alpha": [1,2,3,4,5,6,7,8], "beta": )");
  EXPECT_NE(m.find("bad.json:1:38: not valid JSON"), std::string::npos) << m;

  m = msg("array.json", "[1, 2]");
  EXPECT_NE(m.find("expected a JSON object"), std::string::npos) << m;

  m = msg("unit.json", R"({"unit": 3, "alpha": )" + good8 + R"(, "beta": )" + good8 + "}");
  EXPECT_NE(m.find("\"unit\" must be a string"), std::string::npos) << m;

  m = test::error_of<InputError>([&] { load_coefficients(d.path() / "nonexistent.json"); });
  EXPECT_NE(m.find("cannot open"), std::string::npos) << m;

  m = test::error_of<InputError>([] { load_published("a-9-fpss3"); });
  EXPECT_NE(m.find("no published coefficient set \"a-9-fpss3\""), std::string::npos) << m;
}

TEST(Coefficients, NonFiniteValuesInAJsonObjectAreRefused) {
  nlohmann::json j = {{"alpha", {1, 2, 3, 4, 5, 6, 7, 8}}, {"beta", {1, 2, 3, 4, 5, 6, 7, 8}}};
  j["beta"][4] = std::numeric_limits<double>::quiet_NaN();
  const std::string m = test::error_of<InputError>([&] { parse_coefficients(j, "mem"); });
  EXPECT_NE(m.find("mem: \"beta\"[4] (C5) must be a finite number"), std::string::npos) << m;
}

TEST(CoefficientFile, EveryHostileFileIsAnInputErrorNamingFileAndKey) {
  TempDir d;
  auto load_error = [&](const std::string& name, const std::string& text) {
    const auto p = d.write(name, text);
    return test::error_of<InputError>([&] { load_coefficients(p); });
  };
  std::string m = load_error("deep.json", std::string(200000, '[') + std::string(200000, ']'));
  EXPECT_NE(m.find("deep.json:1:65: nested deeper than 64 levels"), std::string::npos) << m;
  m = load_error("dup.json", "{\"alpha\": " + kGood8 + ", \"beta\": " + kGood8 + ", \"beta\": " + kGood8 + "}");
  EXPECT_NE(m.find("dup.json:1:"), std::string::npos) << m;
  EXPECT_NE(m.find("key \"beta\" given twice"), std::string::npos) << m;
  m = load_error("huge.json", R"({"alpha": [0, 5e-7, 3e-5, 3e-4, 3.4, -1e-4, 1e-4, 1.7], "beta": [1e308, 5e-7, 3e-5, 3e-4, 3.4, -1e-4, 1e-4, 1.7]})");
  EXPECT_NE(m.find("huge.json: \"beta\"[0] (C1) = 1e+308 is beyond +-1000"), std::string::npos) << m;
  m = load_error("over.json", R"({"alpha": [1e400, 5e-7, 3e-5, 3e-4, 3.4, -1e-4, 1e-4, 1.7]})");
  EXPECT_NE(m.find("over.json:1:"), std::string::npos) << m;
  m = test::error_of<InputError>([&] { load_coefficients("/dev/zero"); });
  EXPECT_NE(m.find("/dev/zero: not a regular file"), std::string::npos) << m;
  m = test::error_of<InputError>([&] { load_coefficients(d.path()); });
  EXPECT_NE(m.find("not a regular file (a folder); expected the coefficient file"), std::string::npos) << m;
  const auto big = d.write("big.json", "{\"unit\": \"" + std::string(kMaxConfigFileBytes, 'x') + "\"}");
  m = test::error_of<InputError>([&] { load_coefficients(big); });
  EXPECT_NE(m.find("more than the 16777216 bytes a coefficient file may have"), std::string::npos) << m;
}

}  // namespace
}  // namespace fpss
