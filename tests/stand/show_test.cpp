// `fpss-stand show`, `report`, `runs`, `calibrate --json` and an unknown command, on run folders
// the real binary made on the emulated bench; the report's verdict banner; the 1-based points.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <fstream>

#include <nlohmann/json.hpp>

#include "calib/samples.h"
#include "tests/procedures/run_util.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using test::CommandResult;
using testing::HasSubstr;
using testing::Not;

std::string grid() { return (test::source_dir() / "procedures" / "discrete_grid.yaml").string(); }

// One completed run of the discrete grid and one whose check fails, made once for the suite.
class ShowCli : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    tmp_ = new test::TempDir("show");
    const fs::path runs = *tmp_ / "runs";
    const CommandResult ok = test::run_stand({"run", grid(), "--emulate", "--speed", "50", "--runs-dir", runs.string()}, tmp_->path(), "ok");
    ASSERT_EQ(ok.code, 0) << ok.err;
    good_ = test::run_dirs(runs).at(0);
    // The same grid with a check no sensor meets (0.01 arcsec): the run fails on its check.
    std::string text = test::read_file(grid());
    const auto at = text.find("mean_abs_arcsec: 0.8");
    ASSERT_NE(at, std::string::npos);
    text.replace(at, 20, "mean_abs_arcsec: 0.01");
    const fs::path strict = tmp_->write("strict_grid.yaml", text);
    const fs::path runs2 = *tmp_ / "runs2";
    const CommandResult bad = test::run_stand({"run", strict.string(), "--emulate", "--speed", "50", "--runs-dir", runs2.string()}, tmp_->path(), "bad");
    ASSERT_EQ(bad.code, 1) << bad.err;
    bad_out_ = bad.out + bad.err;
    failed_ = test::run_dirs(runs2).at(0);
  }
  static void TearDownTestSuite() { delete tmp_; }

  static test::TempDir* tmp_;
  static fs::path good_, failed_;
  static std::string bad_out_;
};
test::TempDir* ShowCli::tmp_ = nullptr;
fs::path ShowCli::good_, ShowCli::failed_;
std::string ShowCli::bad_out_;

// A run's id: run.json's run_id (the catalogue's UUIDv7), not its folder's name.
std::string run_id_of(const fs::path& dir) {
  return nlohmann::json::parse(test::read_file(dir / "run.json"))["run_id"].get<std::string>();
}

TEST_F(ShowCli, ShowsARunByPathAndById) {
  const CommandResult by_path = test::run_stand({"show", good_.string()}, tmp_->path(), "show1");
  ASSERT_EQ(by_path.code, 0) << by_path.err;
  EXPECT_THAT(by_path.out, HasSubstr("run " + run_id_of(good_)));
  EXPECT_THAT(by_path.out, HasSubstr("outcome    completed"));
  EXPECT_THAT(by_path.out, HasSubstr("verdict    PASS"));
  EXPECT_THAT(by_path.out, HasSubstr("points     113/113"));
  EXPECT_THAT(by_path.out, HasSubstr("residuals  pitch mean |r| "));
  EXPECT_THAT(by_path.out, HasSubstr("samples.csv"));
  const CommandResult by_id = test::run_stand({"show", good_.filename().string(), "--runs-dir", good_.parent_path().string()},
                                              tmp_->path(), "show2");
  ASSERT_EQ(by_id.code, 0) << by_id.err;
  EXPECT_EQ(by_id.out, by_path.out);
  // The catalogue's run id (run.json's run_id, a UUIDv7) finds the folder too.
  const std::string uuid = run_id_of(good_);
  ASSERT_NE(uuid, good_.filename().string());
  const CommandResult by_uuid = test::run_stand({"show", uuid, "--runs-dir", good_.parent_path().string()},
                                                tmp_->path(), "show4");
  ASSERT_EQ(by_uuid.code, 0) << by_uuid.err;
  EXPECT_EQ(by_uuid.out, by_path.out);
  const CommandResult missing = test::run_stand({"show", "no-such-run", "--runs-dir", good_.parent_path().string()},
                                                tmp_->path(), "show3");
  EXPECT_EQ(missing.code, 2);
  EXPECT_THAT(missing.err, HasSubstr("no-such-run"));
}

TEST_F(ShowCli, ShowJsonCarriesOutcomeVerdictPointsResidualsFiles) {
  const CommandResult r = test::run_stand({"show", good_.string(), "--json"}, tmp_->path(), "showjson");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["run_id"], run_id_of(good_));
  EXPECT_EQ(j["outcome"], "completed");
  EXPECT_EQ(j["verdict"], "pass");
  EXPECT_EQ(j["points"]["done"], 113);
  EXPECT_EQ(j["points"]["total"], 113);
  // The residuals are calibration.json's, the calibrator's Table 1.
  const auto cal = nlohmann::json::parse(test::read_file(good_ / "calibration.json"));
  EXPECT_EQ(j["residuals"]["pitch"]["mean_abs_arcsec"], cal["residuals"]["pitch"]["mean_abs_arcsec"]);
  EXPECT_LT(j["residuals"]["yaw"]["mean_abs_arcsec"].get<double>(), 0.8);
  EXPECT_THAT(j["files"].get<std::vector<std::string>>(), testing::Contains("report.html"));

  const CommandResult f = test::run_stand({"show", failed_.string(), "--json"}, tmp_->path(), "showfail");
  ASSERT_EQ(f.code, 0) << f.err;
  const auto jf = nlohmann::json::parse(f.out);
  EXPECT_EQ(jf["verdict"], "fail");
  EXPECT_EQ(jf["stop_cause"], "check_failed");
  EXPECT_THAT(jf["verdict_reason"].get<std::string>(), HasSubstr("mean |residual|"));
}

TEST_F(ShowCli, TheReportOpensWithAPassOrFailBanner) {
  const std::string good = test::read_file(good_ / "report.html");
  const std::string bad = test::read_file(failed_ / "report.html");
  const auto good_banner = good.find("id=\"verdict\"");
  ASSERT_NE(good_banner, std::string::npos);
  EXPECT_LT(good_banner, good.find("<nav>"));  // above everything but the title
  EXPECT_THAT(good.substr(good_banner, 300), HasSubstr(">PASS<"));
  const auto bad_banner = bad.find("id=\"verdict\"");
  ASSERT_NE(bad_banner, std::string::npos);
  EXPECT_LT(bad_banner, bad.find("<nav>"));
  EXPECT_THAT(bad.substr(bad_banner, 400), HasSubstr(">FAIL<"));
  EXPECT_THAT(bad.substr(bad_banner, 600), HasSubstr("0.01 arcsec"));
}

TEST_F(ShowCli, AFailedCheckWithAllPointsDoesNotSuggestAResume) {
  EXPECT_THAT(bad_out_, HasSubstr("(check): pitch mean |residual|"));
  EXPECT_THAT(bad_out_, Not(HasSubstr("resume with:")));
  // 0.3 arcsec against 0.01 is 30x: not absurd, no word on the axis mapping.
  EXPECT_THAT(bad_out_, Not(HasSubstr("axis mapping")));
}

TEST_F(ShowCli, ReportDrawsTheReportAgain) {
  const fs::path page = good_ / "report.html";
  fs::remove(page);
  const CommandResult r = test::run_stand({"report", good_.filename().string(), "--runs-dir", good_.parent_path().string()},
                                          tmp_->path(), "report");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("report.html"));
  ASSERT_TRUE(fs::exists(page));
  EXPECT_THAT(test::read_file(page), HasSubstr("Calibration summary (Table 1 form)"));
  EXPECT_THAT(test::read_file(page), HasSubstr("method: differences"));
  // A re-calibration (here by the absolute method) then `report`: the page is the new calibration's.
  const fs::path cal = good_ / "calibration.json";
  const CommandResult recal = test::run_stand(
      {"calibrate", "--data", (good_ / "samples.csv").string(), "--out", cal.string(), "--method", "absolute"},
      tmp_->path(), "recal");
  ASSERT_EQ(recal.code, 0) << recal.err;
  const CommandResult again = test::run_stand({"report", good_.string()}, tmp_->path(), "report2");
  ASSERT_EQ(again.code, 0) << again.err;
  EXPECT_THAT(test::read_file(page), HasSubstr("method: absolute"));
}

TEST_F(ShowCli, RunsShowsOutcomesAndVerdictColumns) {
  const CommandResult r = test::run_stand({"runs", "--runs-dir", good_.parent_path().string()}, tmp_->path(), "runs");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("VERDICT"));
  EXPECT_THAT(r.out, HasSubstr(run_id_of(good_)));
  const CommandResult j = test::run_stand({"runs", "--runs-dir", good_.parent_path().string(), "--json"}, tmp_->path(), "runsj");
  ASSERT_EQ(j.code, 0) << j.err;
  const auto list = nlohmann::json::parse(j.out);
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0]["points"]["done"], 113);
  EXPECT_EQ(list[0]["points"]["total"], 113);
  EXPECT_TRUE(list[0]["verdict"].is_null());  // not an acceptance
}

// A run in progress: `runs` and `show` give its points done so far (from its journal) and its pid.
TEST(ShowLive, RunsAndShowGiveALiveRunsProgress) {
  test::TempDir tmp("show-live");
  const fs::path runs = tmp / "runs";
  test::Child run = test::start_stand({"run", grid(), "--emulate", "--speed", "2", "--runs-dir", runs.string()}, tmp.path(), "live");
  ASSERT_TRUE(test::wait_until([&] { return test::journaled_points(runs) >= 2; }, 120)) << run.err();
  const CommandResult listed = test::run_stand({"runs", "--runs-dir", runs.string()}, tmp.path(), "runs");
  ASSERT_EQ(listed.code, 0) << listed.err;
  EXPECT_THAT(listed.out, testing::ContainsRegex("running [0-9]+/113 points \\(pid " + std::to_string(run.pid()) + "\\)"));
  const CommandResult shown = test::run_stand({"show", test::run_dirs(runs).at(0).string(), "--json"}, tmp.path(), "show");
  ASSERT_EQ(shown.code, 0) << shown.err;
  const auto j = nlohmann::json::parse(shown.out);
  EXPECT_EQ(j["outcome"], "running");
  EXPECT_EQ(j["verdict"], "running");
  EXPECT_GE(j["points"]["done"].get<int64_t>(), 2);
  EXPECT_EQ(j["points"]["total"], 113);
  run.signal(SIGTERM);
  EXPECT_EQ(run.wait(60), 1);
}

TEST_F(ShowCli, PointsAreNumberedFromOneInTheJournalTheEventsAndRunJson) {
  std::ifstream journal(good_ / "points.jsonl");
  std::string line;
  int64_t expected = 0;
  while (std::getline(journal, line)) {
    const auto j = nlohmann::json::parse(line);
    EXPECT_EQ(j["point"], ++expected);
    EXPECT_EQ(j["step"], expected);
  }
  EXPECT_EQ(expected, 113);
  EXPECT_THAT(test::read_file(good_ / "events.jsonl"), HasSubstr("\"first_point\":1"));
  const auto doc = nlohmann::json::parse(test::read_file(good_ / "run.json"));
  EXPECT_EQ(doc["sessions"][0]["first_point"], 1);
}

TEST_F(ShowCli, CalibrateJsonIsMachineReadable) {
  const fs::path out = *tmp_ / "cal.json";
  const CommandResult r = test::run_stand(
      {"calibrate", "--data", (good_ / "samples.csv").string(), "--out", out.string(), "--json"}, tmp_->path(), "calj");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["file"], out.string());
  EXPECT_EQ(j["calibration"], nlohmann::json::parse(test::read_file(out)));
  EXPECT_TRUE(j["calibration"]["residuals"]["pitch"]["mean_abs_arcsec"].is_number());
}

// Offline, the same recording with glitch frames (one axis 400 counts off, as a glitching unit
// sends them): `calibrate` then `report` give one set of numbers, and name the frames left out.
TEST_F(ShowCli, CalibrateThenReportOnAGlitchingRecordingAgree) {
  const fs::path dir = *tmp_ / "glitched";
  fs::create_directories(dir);
  SampleTable t = read_samples_csv(good_ / "samples.csv");
  size_t spiked[2] = {0, 0};
  for (size_t i = 7, k = 0; i < t.size(); i += 97, ++k) {
    if (t.phase[i] != Phase::null && t.phase[i] != Phase::offset) continue;
    (k % 2 ? t.counts_beta : t.counts_alpha)[i] += k % 3 ? 400 : -400;
    ++spiked[k % 2];
  }
  ASSERT_GT(spiked[0], 5u);
  ASSERT_GT(spiked[1], 5u);
  write_samples_csv(dir / "samples.csv", t);
  fs::copy_file(good_ / "run.json", dir / "run.json");
  const CommandResult cal = test::run_stand(
      {"calibrate", "--data", (dir / "samples.csv").string(), "--out", (dir / "calibration.json").string()},
      tmp_->path(), "glitch-cal");
  ASSERT_EQ(cal.code, 0) << cal.err;
  const CommandResult rep = test::run_stand({"report", dir.string()}, tmp_->path(), "glitch-report");
  ASSERT_EQ(rep.code, 0) << rep.err;
  const auto j = nlohmann::json::parse(test::read_file(dir / "calibration.json"));
  EXPECT_EQ(j["outliers"]["pitch"]["outlier_frames"], spiked[0]);
  EXPECT_EQ(j["outliers"]["yaw"]["outlier_frames"], spiked[1]);
  EXPECT_EQ(j["outliers"]["outlier_frames"], spiked[0] + spiked[1]);
  // The glitches stay out: the fit is as good as on the clean recording.
  const auto clean = nlohmann::json::parse(test::read_file(good_ / "calibration.json"));
  for (const char* axis : {"pitch", "yaw"}) {
    const auto& r = j["residuals"][axis];
    EXPECT_LT(r["max_abs_arcsec"].get<double>(), clean["residuals"][axis]["max_abs_arcsec"].get<double>() + 0.3) << axis;
  }
  const std::string html = test::read_file(dir / "report.html");
  EXPECT_THAT(html, Not(HasSubstr("differs from the residuals")));
  for (const char* axis : {"pitch", "yaw"}) {
    const auto& r = j["residuals"][axis];
    EXPECT_THAT(html, HasSubstr(fmt::format("{:.2f} &plusmn; {:.2f}</td><td>{:.2f}</td>", r["mean_abs_arcsec"].get<double>(),
                                            r["sd_arcsec"].get<double>(), r["max_abs_arcsec"].get<double>())))
        << axis;
  }
  EXPECT_THAT(html, HasSubstr(fmt::format("Outlier frames: {} of ", spiked[0] + spiked[1])));
  EXPECT_THAT(html, HasSubstr(fmt::format("pitch (alpha) {} (", spiked[0])));
  EXPECT_THAT(html, HasSubstr(fmt::format("yaw (beta) {} (", spiked[1])));
  // The diagnosis judges the dwell frames by the same reduction: GAP.json counts the same frames.
  const CommandResult dia = test::run_stand({"diagnose", "--model", (good_ / "calibration.json").string(), "--data",
                                             (dir / "samples.csv").string(), "--out", (dir / "GAP.json").string(), "--partial"},
                                            tmp_->path(), "glitch-diagnose");
  ASSERT_EQ(dia.code, 0) << dia.err;
  const auto gap = nlohmann::json::parse(test::read_file(dir / "GAP.json"));
  EXPECT_EQ(gap["outliers"]["dwells"], j["outliers"]);
  EXPECT_GE(gap["outliers"]["pitch"]["outlier_frames"].get<size_t>(), spiked[0]);
  EXPECT_GE(gap["outliers"]["yaw"]["outlier_frames"].get<size_t>(), spiked[1]);
}

// A folder that is not a run folder, or whose files do not parse, is bad input (exit 2, the file named).
TEST(ShowHostile, BadRunFoldersAreExitTwoNamingTheFile) {
  test::TempDir tmp("show-hostile");
  const fs::path dir = tmp / "run";
  fs::create_directories(dir);
  auto show = [&](const std::string& tag) { return test::run_stand({"show", dir.string(), "--json"}, tmp.path(), tag); };
  CommandResult r = show("none");
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr("not a run folder"));
  test::write_file(dir / "run.json", "{\"outcome\": ");
  r = show("torn");
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr("run.json"));
  // Wrong types are bad input naming the key (run.json is read as one type, stand/catalogue/run_file.h).
  const std::string good_head =
      "{\"procedure\": {\"name\": \"g\", \"sha256\": \"x\", \"text\": \"t\"}, \"unit\": \"U\", \"emulated\": true,"
      " \"started_utc\": \"2024-05-01T12:00:00Z\", \"sessions\": [],";
  test::write_file(dir / "run.json", good_head + " \"outcome\": \"failed\", \"points\": {\"total\": \"many\", \"completed\": 0},"
                                                 " \"files\": {}}");
  r = show("types");
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr("run.json"));
  EXPECT_THAT(r.err, HasSubstr("\"points.total\""));
  // A calibration named out of its folder is not followed.
  test::write_file(dir / "run.json", good_head + " \"outcome\": \"failed\", \"points\": {\"total\": 4, \"completed\": 0},"
                                                 " \"files\": {\"calibration\": \"../../etc/passwd\"}}");
  r = show("types");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["emulated"], true);
  EXPECT_EQ(j["points"]["total"], 4);
  EXPECT_TRUE(j["calibration"].is_null());
  EXPECT_EQ(j["verdict"], "incomplete");
  test::write_file(dir / "calibration.json", "{\"residuals\": {\"pitch\": {\"mean_abs_arcsec\": \"small\"}}}");
  r = show("cal");
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr("calibration.json"));
  EXPECT_THAT(r.err, HasSubstr("mean_abs_arcsec"));
}

TEST(Cli, AnUnknownCommandNamesItself) {
  test::TempDir tmp("unknown");
  const CommandResult r = test::run_stand({"frobnicate", "x"}, tmp.path(), "unknown");
  EXPECT_EQ(r.code, 2);
  EXPECT_THAT(r.err, HasSubstr("unknown command 'frobnicate'; see --help"));
  EXPECT_THAT(r.err, Not(HasSubstr("A subcommand is required")));
  const CommandResult none = test::run_stand({}, tmp.path(), "none");
  EXPECT_EQ(none.code, 2);
  const CommandResult known = test::run_stand({"show", "--help"}, tmp.path(), "help");
  EXPECT_EQ(known.code, 0) << known.err;
}

}  // namespace
}  // namespace fpss
