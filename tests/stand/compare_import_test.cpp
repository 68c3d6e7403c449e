// fpss-stand import / compare / history over a real catalogue file: the paper's seven calibrations
// of FPSS1 and FPSS2 as two units' histories, and V against VI checked against eq. 1 computed here.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "stand/catalogue/sqlite_catalogue.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {
namespace fs = std::filesystem;

const fs::path kPublished = test::source_dir() / "calib/data/published";

using test::CommandResult;
using test::run_stand_shell;

// The paper's calibrations in order, with the dates they were determined (Tables A-2..A-7).
// The prelaunch set (A-1) carries no date in the paper: SMM's launch day stands in for it.
struct PaperCal {
  const char* table;
  const char* label;
  const char* date;
};
constexpr PaperCal kPaper[] = {{"a-1", "PRELAUNCH", "1980-02-14"}, {"a-2", "I", "1980-03-18"},
                               {"a-3", "II", "1980-06-11"},        {"a-4", "III", "1980-06-27"},
                               {"a-5", "IV", "1980-07-17"},        {"a-6", "V", "1980-08-27"},
                               {"a-7", "VI", "1980-09-04"}};

fs::path published(const std::string& table, const std::string& unit) {
  return kPublished / (table + "-" + unit + ".json");
}

nlohmann::json read_json(const fs::path& p) {
  std::ifstream f(p);
  return nlohmann::json::parse(f);
}

// ---- eq. 1 written out here, on coefficients read straight from the JSON files ----
constexpr double kPi = 3.14159265358979323846;
constexpr double kArcsecPerRad = 648000.0 / kPi;

double eq1(const std::vector<double>& c, double n) {
  return c[0] + c[1] * n + c[2] * std::sin(c[3] * n + c[4]) + c[5] * std::sin(c[6] * n + c[7]);
}

struct Figures {
  double max_abs = 0, rms = 0, mean = 0, max_abs_offset_removed = 0;
};

// B - A at every integer count whose angle under A is within +-range_deg.
Figures figures(const std::vector<double>& a, const std::vector<double>& b, double range_deg) {
  const double limit = range_deg * kPi / 180.0;
  std::vector<double> d;
  for (int n = -32768; n <= 32767; ++n) {
    if (std::fabs(eq1(a, n)) <= limit) d.push_back((eq1(b, n) - eq1(a, n)) * kArcsecPerRad);
  }
  Figures f;
  double s = 0, s2 = 0;
  for (double v : d) {
    s += v;
    s2 += v * v;
    f.max_abs = std::max(f.max_abs, std::fabs(v));
  }
  f.mean = s / static_cast<double>(d.size());
  f.rms = std::sqrt(s2 / static_cast<double>(d.size()));
  for (double v : d) f.max_abs_offset_removed = std::max(f.max_abs_offset_removed, std::fabs(v - f.mean));
  return f;
}

void expect_matches(const nlohmann::json& got, const Figures& want) {
  EXPECT_NEAR(got.at("max_abs_arcsec").get<double>(), want.max_abs, 1e-6);
  EXPECT_NEAR(got.at("rms_arcsec").get<double>(), want.rms, 1e-6);
  EXPECT_NEAR(got.at("max_abs_offset_removed_arcsec").get<double>(), want.max_abs_offset_removed, 1e-6);
}

class PaperHistories : public ::testing::Test {
 protected:
  void SetUp() override {
    db_ = scratch_.path() / "cat" / "stand.db";
    for (const char* unit : {"fpss1", "fpss2"}) {
      const std::string serial = unit == std::string("fpss1") ? "SMM-FPSS1" : "SMM-FPSS2";
      for (const auto& p : kPaper) {
        const CommandResult r = run_stand_shell(
            "import '" + published(p.table, unit).string() + "' --unit " + serial + " --date " + p.date + " --db '" +
                db_.string() + "'",
            scratch_.path());
        ASSERT_EQ(r.code, 0) << p.table << " " << unit << ": " << r.err;
      }
    }
  }
  CommandResult cli(const std::string& args) {
    return run_stand_shell(args + " --db '" + db_.string() + "'", scratch_.path());
  }

  test::TempDir scratch_{"compare-import"};
  fs::path db_;
};

TEST_F(PaperHistories, ImportsBecomeTwoUnitsHistoriesInDateOrder) {
  SqliteCatalogue cat(db_, Catalogue::Mode::read_only);
  EXPECT_EQ(cat.integrity_check(), "ok");
  for (const char* unit : {"fpss1", "fpss2"}) {
    const std::string serial = unit == std::string("fpss1") ? "SMM-FPSS1" : "SMM-FPSS2";
    const auto h = cat.unit_history(serial);
    ASSERT_EQ(h.size(), std::size(kPaper));
    for (size_t i = 0; i < h.size(); ++i) {
      EXPECT_EQ(h[i].unit, serial);
      EXPECT_EQ(h[i].source, "import");
      EXPECT_FALSE(h[i].run_id.has_value());
      EXPECT_EQ(h[i].label, kPaper[i].label);
      EXPECT_EQ(h[i].date_utc, kPaper[i].date);
      EXPECT_EQ(h[i].method, "imported");
      EXPECT_EQ(h[i].coefficients, read_json(published(kPaper[i].table, unit)));  // as printed, digit for digit
      EXPECT_EQ(fs::path(h[i].source_ref).filename(), published(kPaper[i].table, unit).filename());
    }
  }
}

TEST_F(PaperHistories, CompareVWithViForFpss1MatchesEq1Independently) {
  SqliteCatalogue cat(db_, Catalogue::Mode::read_only);
  const auto h = cat.unit_history("SMM-FPSS1");
  ASSERT_EQ(h[5].label, "V");
  ASSERT_EQ(h[6].label, "VI");
  const CommandResult r = cli("compare cal:" + std::to_string(h[5].id) + " cal:" + std::to_string(h[6].id) + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j.size(), 2u);

  const auto v = read_json(published("a-6", "fpss1")), vi = read_json(published("a-7", "fpss1"));
  const Figures alpha = figures(v["alpha"].get<std::vector<double>>(), vi["alpha"].get<std::vector<double>>(), 0.35);
  const Figures beta = figures(v["beta"].get<std::vector<double>>(), vi["beta"].get<std::vector<double>>(), 0.35);
  expect_matches(j.at("alpha"), alpha);
  expect_matches(j.at("beta"), beta);

  // The degradation the paper's Figures 1-2 show: both axes changed shape by arcseconds between
  // V and VI, beyond the 1 arcsec a history flags; alpha also moved by the August 22 slew.
  EXPECT_GT(alpha.max_abs_offset_removed, 2.0);
  EXPECT_GT(beta.max_abs_offset_removed, 2.0);
  EXPECT_LT(alpha.mean, -40.0);

  // The same figures from the files themselves, and from the published names.
  const CommandResult files = run_stand_shell("compare '" + published("a-6", "fpss1").string() + "' '" +
                                published("a-7", "fpss1").string() + "' --json --range-deg 0.35",
                            scratch_.path());
  ASSERT_EQ(files.code, 0) << files.err;
  EXPECT_EQ(nlohmann::json::parse(files.out), j);
  const CommandResult named = run_stand_shell("compare a-6-fpss1 a-7-fpss1 --json", scratch_.path());
  ASSERT_EQ(named.code, 0) << named.err;
  EXPECT_EQ(nlohmann::json::parse(named.out), j);
}

TEST_F(PaperHistories, ViBetaIsComparedAsPrintedNotWithB7Corrected) {
  // Table A-7 FPSS1 B7 = 0.1877559e-5 looks misprinted (every other FPSS1 B7 is two orders larger). compare takes it as printed:
  // VI's second beta sinusoid is then nearly a constant over the range. With B7 read as 1e-4
  // the beta figures come out differently, so the two readings can be told apart.
  const auto v = read_json(published("a-6", "fpss1")), vi = read_json(published("a-7", "fpss1"));
  auto vi_fixed = vi["beta"].get<std::vector<double>>();
  vi_fixed[6] = 0.1877559e-3;
  const Figures printed = figures(v["beta"].get<std::vector<double>>(), vi["beta"].get<std::vector<double>>(), 0.35);
  const Figures fixed = figures(v["beta"].get<std::vector<double>>(), vi_fixed, 0.35);
  ASSERT_GT(std::fabs(printed.max_abs_offset_removed - fixed.max_abs_offset_removed), 0.3);
  ASSERT_GT(std::fabs(printed.mean - fixed.mean), 1.0);
  const CommandResult r = run_stand_shell("compare a-6-fpss1 a-7-fpss1 --json", scratch_.path());
  ASSERT_EQ(r.code, 0) << r.err;
  expect_matches(nlohmann::json::parse(r.out).at("beta"), printed);
}

TEST_F(PaperHistories, FpssTwoVWithViAndRangeOption) {
  const auto v = read_json(published("a-6", "fpss2")), vi = read_json(published("a-7", "fpss2"));
  for (double range : {0.2, 0.35, 0.42}) {
    const auto r =
        run_stand_shell("compare a-6-fpss2 a-7-fpss2 --json --range-deg " + std::to_string(range), scratch_.path());
    ASSERT_EQ(r.code, 0) << r.err;
    const auto j = nlohmann::json::parse(r.out);
    for (const char* axis : {"alpha", "beta"}) {
      SCOPED_TRACE(std::string(axis) + " +-" + std::to_string(range));
      expect_matches(j.at(axis), figures(v[axis].get<std::vector<double>>(), vi[axis].get<std::vector<double>>(), range));
    }
  }
}

TEST_F(PaperHistories, TableAndPlot) {
  const fs::path svg = scratch_.path() / "plots" / "v-vi.svg";
  const CommandResult r = run_stand_shell("compare a-6-fpss1 a-7-fpss1 --plot '" + svg.string() + "'", scratch_.path());
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("alpha"), std::string::npos);
  EXPECT_NE(r.out.find("beta"), std::string::npos);
  EXPECT_NE(r.out.find("50.343"), std::string::npos) << r.out;  // alpha max |B - A|, as eq. 1 gives it
  ASSERT_TRUE(fs::exists(svg));
  std::ifstream f(svg);
  const std::string text((std::istreambuf_iterator<char>(f)), {});
  EXPECT_NE(text.find("<svg"), std::string::npos);
  EXPECT_TRUE(fs::exists(scratch_.path() / "plots" / "v-vi.dat"));
  EXPECT_TRUE(fs::exists(scratch_.path() / "plots" / "v-vi.gp"));
}

TEST_F(PaperHistories, ALabelOrPathHoldingShellTextRunsNothing) {
  // An imported file whose calibration label, and a --plot path, hold backquotes and $(...).
  const fs::path x1 = scratch_.path() / "X1", x2 = scratch_.path() / "X2", x3 = scratch_.path() / "X3";
  nlohmann::json j = nlohmann::json::parse(test::read_file(published("a-7", "fpss1")));
  j["calibration"] = "VI `touch " + x1.string() + "` $(touch " + x2.string() + ")";
  const fs::path hostile = test::write_file(scratch_.path() / "hostile.json", j.dump());
  auto r = cli("import '" + hostile.string() + "' --unit EVIL --date 1980-09-04 --json");
  ASSERT_EQ(r.code, 0) << r.err;
  const int64_t id = nlohmann::json::parse(r.out).at("id").get<int64_t>();
  const fs::path svg = scratch_.path() / ("p `touch " + x3.string() + "` $(touch " + x3.string() + ").svg");
  r = run_stand_shell("compare a-6-fpss1 cal:" + std::to_string(id) + " --plot '" + svg.string() + "' --db '" +
                          db_.string() + "'",
                      scratch_.path());
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(svg));
  EXPECT_FALSE(fs::exists(x1));
  EXPECT_FALSE(fs::exists(x2));
  EXPECT_FALSE(fs::exists(x3));
}

TEST_F(PaperHistories, ReimportIsANoOpAndReportsTheChange) {
  const auto r = cli("import '" + published("a-7", "fpss1").string() + "' --unit SMM-FPSS1 --date 1980-09-04 --json");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j["already_present"].get<bool>());
  EXPECT_TRUE(j["change"]["flagged"].get<bool>());
  EXPECT_EQ(j["change"]["previous_date"], "1980-08-27");
  SqliteCatalogue cat(db_, Catalogue::Mode::read_only);
  EXPECT_EQ(cat.unit_history("SMM-FPSS1").size(), std::size(kPaper));
}

TEST_F(PaperHistories, HistoryFlagsTheLatestChangeBeyondTheLimit) {
  // V -> VI moved FPSS1 by 50 arcsec (alpha, incl. the slew's null shift): flagged at the default 1 arcsec.
  CommandResult r = cli("history SMM-FPSS1 --json");
  ASSERT_EQ(r.code, 0) << r.err;
  auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["limit_arcsec"].get<double>(), 1.0);
  EXPECT_TRUE(j["latest_flagged"].get<bool>());
  const auto& cals = j["calibrations"];
  ASSERT_EQ(cals.size(), std::size(kPaper));
  EXPECT_FALSE(cals[0].contains("change_arcsec"));
  const auto v = read_json(published("a-6", "fpss1")), vi = read_json(published("a-7", "fpss1"));
  const double want = std::max(
      figures(v["alpha"].get<std::vector<double>>(), vi["alpha"].get<std::vector<double>>(), 0.35).max_abs,
      figures(v["beta"].get<std::vector<double>>(), vi["beta"].get<std::vector<double>>(), 0.35).max_abs);
  EXPECT_NEAR(cals[6]["change_arcsec"].get<double>(), want, 1e-6);
  r = cli("history SMM-FPSS1 --limit-arcsec 60 --json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_FALSE(nlohmann::json::parse(r.out)["latest_flagged"].get<bool>());
  r = cli("history SMM-FPSS1");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("CHANGED beyond the limit"), std::string::npos) << r.out;

  // A later calibration 0.5 arcsec from VI on beta only (a null shift): within 1 arcsec, beyond 0.3.
  auto later = vi;
  later["beta"][0] = later["beta"][0].get<double>() + 0.5 / kArcsecPerRad;
  later.erase("calibration");
  const fs::path later_file = scratch_.path() / "later.json";
  std::ofstream(later_file) << later.dump();
  r = cli("import '" + later_file.string() + "' --unit SMM-FPSS1 --date 1980-10-01T12:00:00Z --label VII");
  ASSERT_EQ(r.code, 0) << r.err;
  r = cli("history SMM-FPSS1 --json");
  j = nlohmann::json::parse(r.out);
  EXPECT_FALSE(j["latest_flagged"].get<bool>());
  EXPECT_EQ(j["calibrations"].back()["label"], "VII");
  EXPECT_NEAR(j["calibrations"].back()["change_arcsec"].get<double>(), 0.5, 1e-6);
  EXPECT_NEAR(j["calibrations"].back()["change_offset_removed_arcsec"].get<double>(), 0.0, 1e-6);
  r = cli("history SMM-FPSS1 --json --limit-arcsec 0.3");
  EXPECT_TRUE(nlohmann::json::parse(r.out)["latest_flagged"].get<bool>());
  EXPECT_EQ(cli("history SMM-FPSS1 --limit-arcsec 0").code, 2);
}

TEST_F(PaperHistories, BadInputIsExitTwoAndRecordsNothing) {
  const fs::path bad = scratch_.path() / "bad.json";
  {
    std::ofstream(bad) << R"({"alpha": [1, 2, 3], "beta": [1,2,3,4,5,6,7,8]})";
  }
  const fs::path garbage = scratch_.path() / "garbage.json";
  {
    std::ofstream(garbage) << "{ not json";
  }
  const std::string good = published("a-6", "fpss1").string();
  struct Case {
    std::string args, needle;
  } cases[] = {
      {"import '" + bad.string() + "' --unit X --date 2024-01-01", "bad.json"},
      {"import '" + garbage.string() + "' --unit X --date 2024-01-01", "garbage.json"},
      {"import '" + (scratch_.path() / "missing.json").string() + "' --unit X --date 2024-01-01", "missing.json"},
      {"import '" + good + "' --unit X --date 2024-02-30", "no such day"},
      {"import '" + good + "' --unit X --date yesterday", "ISO 8601"},
      {"import '" + good + "' --unit X", "--date"},
  };
  for (const auto& c : cases) {
    const CommandResult r = cli(c.args);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.needle), std::string::npos) << c.args << "\n" << r.err;
  }
  SqliteCatalogue cat(db_, Catalogue::Mode::read_only);
  EXPECT_FALSE(cat.has_unit("X"));

  EXPECT_EQ(run_stand_shell("compare a-6-fpss1 a-7-fpss1 --range-deg -1", scratch_.path()).code, 2);
  EXPECT_EQ(run_stand_shell("compare a-6-fpss1 nonsense.json", scratch_.path()).code, 2);
  EXPECT_EQ(cli("compare cal:999 cal:1").code, 2);
  EXPECT_EQ(cli("compare cal:x cal:1").code, 2);
}

}  // namespace
}  // namespace fpss
