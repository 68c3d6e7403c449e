// `fpss-stand accept` end to end over the real wire: the emulator child over Modbus TCP and a pty,
// the stand-file path, a real SQLite catalogue shared by two acceptances at once, and bad input.
// The criteria themselves are judged in-process in acceptance_test.cpp.
#include <signal.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "procedures/procedure.h"
#include "stand/acceptance/acceptance.h"
#include "stand/catalogue/sqlite_catalogue.h"
#include "stand/session/emulator_process.h"
#include "tests/stand/acceptance_fixtures.h"
#include "tests/stand/emulator_stand.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {
namespace fs = std::filesystem;

using test::CommandResult;
using test::limits;
using test::read_file;
using test::rippled_truth;

class AcceptCli : public ::testing::Test {
 protected:
  fs::path runs() const { return scratch_.path() / "runs"; }
  // Speed-up 40: the whole acceptance (163 points, 5 min of bench time) in about 8 s.
  CommandResult accept(const std::string& args) {
    return test::run_stand_shell(
        "accept --emulate --quiet --speed 40 --json --runs-dir '" + runs().string() + "' " + args, scratch_.path());
  }
  static std::set<std::string> failed(const nlohmann::json& cert) {
    std::set<std::string> f;
    for (const auto& id : cert["failed"]) f.insert(id.get<std::string>());
    return f;
  }
  fs::path write(const std::string& name, const std::string& text) { return scratch_.write(name, text); }
  test::TempDir scratch_{"acceptance"};
};

TEST_F(AcceptCli, GoodUnitPassesIsCertifiedAndRecordedThenAMovedNullFailsAgainstItsHistory) {
  const CommandResult r = accept("--seed 3");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  const auto cert = nlohmann::json::parse(r.out);
  EXPECT_EQ(cert["verdict"], "pass");
  EXPECT_EQ(cert["unit"], "EMU-0001");
  EXPECT_EQ(cert["software"]["version"], FPSS_VERSION);
  EXPECT_EQ(cert["procedure"]["sha256"], sha256_hex(read_file(default_acceptance_procedure_path())));
  EXPECT_EQ(cert["limits"]["sha256"], limits().sha256);
  EXPECT_NE(cert["stand"]["identity"].get<std::string>().find("emulated bench (seed 3"), std::string::npos);
  EXPECT_EQ(cert["run"]["points_completed"], 163);
  ASSERT_EQ(cert["criteria"].size(), 19u);  // no history yet: no consistency criterion
  for (const auto& c : cert["criteria"]) {
    EXPECT_TRUE(c["passed"].get<bool>()) << c.dump();
    EXPECT_TRUE(c["measured"].is_number()) << c.dump();
    EXPECT_FALSE(c["source"].get<std::string>().empty());
  }
  const fs::path dir = cert["run"]["dir"].get<std::string>();
  EXPECT_EQ(nlohmann::json::parse(read_file(dir / "acceptance.json")), cert);
  EXPECT_NE(read_file(dir / "certificate.txt").find("Verdict:    PASS"), std::string::npos);
  {
    // The calibrated angle's U and budget are calibration.json's, copied, and the certificate shows them.
    const auto cal = nlohmann::json::parse(read_file(dir / "calibration.json"))["uncertainties"];
    for (const char* axis : {"pitch", "yaw"}) {
      const auto& mine = cert["calibration_uncertainty"][axis];
      EXPECT_EQ(mine["expanded_uncertainty_max_arcsec"], cal[axis]["expanded_uncertainty_max_arcsec"]);
      EXPECT_EQ(mine["budget"], cal[axis]["budget"]);
      EXPECT_NE(read_file(dir / "certificate.txt")
                    .find(fmt::format("U = {:.4f} arcsec (k = {:.3f}, 95 %", mine["expanded_uncertainty_max_arcsec"].get<double>(),
                                      mine["coverage_factor"].get<double>())),
                std::string::npos)
          << axis;
    }
  }
  const std::string page = read_file(dir / "report.html");
  EXPECT_NE(page.find("id=\"acceptance\""), std::string::npos);
  EXPECT_NE(page.find("Acceptance: PASS"), std::string::npos);
  // The banner on top, and Table 1 on the rows the certificate judged (the calibration's, not the
  // verification's): no note that the two disagree.
  EXPECT_LT(page.find("id=\"verdict\""), page.find("<nav>"));
  EXPECT_NE(page.find(">PASS<"), std::string::npos);
  EXPECT_EQ(page.find("differs from the residuals recomputed here"), std::string::npos);
  EXPECT_NE(page.find("steps 1 to "), std::string::npos);
  EXPECT_EQ(nlohmann::json::parse(read_file(dir / "run.json"))["acceptance"]["verdict"], "pass");
  {
    // `runs` carries the acceptance's verdict.
    const CommandResult listed = test::run_stand({"runs", "--runs-dir", runs().string(), "--json"}, scratch_.path(), "runs");
    ASSERT_EQ(listed.code, 0) << listed.err;
    const auto list = nlohmann::json::parse(listed.out);
    ASSERT_EQ(list.size(), 1u);
    EXPECT_EQ(list[0]["verdict"], "pass");
  }
  {
    SqliteCatalogue cat(Catalogue::default_path(runs()), Catalogue::Mode::read_only);
    const auto acc = cat.unit_acceptances("EMU-0001");
    ASSERT_EQ(acc.size(), 1u);
    EXPECT_TRUE(acc[0].passed);
    EXPECT_EQ(acc[0].run_id.value_or(""), cert["run"]["id"]);
    EXPECT_EQ(acc[0].certificate["verdict"], "pass");
    const auto cals = cat.unit_history("EMU-0001");
    ASSERT_EQ(cals.size(), 1u);
    EXPECT_EQ(cals[0].run_id.value_or(""), cert["run"]["id"]);
  }

  // The same unit again after its null moved by 4 arcsec in yaw (a bias the null condition of
  // this run alone calibrates out): every criterion of the run passes, the history does not.
  const CommandResult moved = accept("--seed 4 --effect bias:pitch_arcsec=0,yaw_arcsec=4");
  ASSERT_EQ(moved.code, 3) << moved.err << moved.out;
  const auto c2 = nlohmann::json::parse(moved.out);
  EXPECT_EQ(c2["verdict"], "fail");
  EXPECT_EQ(failed(c2), std::set<std::string>{"consistency"}) << moved.out;
  for (const auto& c : c2["criteria"]) {
    if (c["id"] == "consistency") {
      EXPECT_NEAR(c["measured"].get<double>(), 4.0, 0.5);
    }
  }
  {
    SqliteCatalogue cat(Catalogue::default_path(runs()), Catalogue::Mode::read_only);
    const auto acc = cat.unit_acceptances("EMU-0001");
    ASSERT_EQ(acc.size(), 2u);
    EXPECT_FALSE(acc[1].passed);
    EXPECT_EQ(cat.unit_history("EMU-0001").size(), 2u);
    EXPECT_EQ(cat.integrity_check(), "ok");
  }

  // Back to the original null: judged against the accepted calibration, not the failed one.
  const CommandResult back = accept("--seed 5");
  ASSERT_EQ(back.code, 0) << back.err << back.out;
  const auto c3 = nlohmann::json::parse(back.out);
  for (const auto& c : c3["criteria"]) {
    if (c["id"] == "consistency") {
      EXPECT_LT(c["measured"].get<double>(), 0.5) << c.dump();
      EXPECT_NE(c["detail"].get<std::string>().find(", accepted"), std::string::npos) << c.dump();
    }
  }
  EXPECT_EQ(c3["criteria"].size(), 20u);
}

TEST_F(AcceptCli, NoisyUnitFailsOnJitter) {
  const fs::path bench = write("noisy.yaml", "count_noise: 10\n");  // 1.1 arcsec per frame, 1 sigma
  const CommandResult r = accept("--bench '" + bench.string() + "'");
  ASSERT_EQ(r.code, 3) << r.err << r.out;
  const auto cert = nlohmann::json::parse(r.out);
  EXPECT_EQ(failed(cert), (std::set<std::string>{"jitter_3sigma_pitch", "jitter_3sigma_yaw"})) << r.out;
}

// A unit that sends glitch frames (valid CRC, one axis 400 counts off, 0.4 % of frames) fails by
// name on outlier_frames, while its transfer function and noise, measured without them, pass; the
// report's Table 1, calibration.json and the certificate give one set of numbers.
TEST_F(AcceptCli, GlitchingUnitFailsByNameOnOutlierFramesWithOneSetOfNumbers) {
  const CommandResult r = accept("--seed 5 --fault sensor_glitch:rate=0.004,counts=400");
  ASSERT_EQ(r.code, 3) << r.err << r.out;
  const auto cert = nlohmann::json::parse(r.out);
  EXPECT_EQ(failed(cert), (std::set<std::string>{"outlier_frames"})) << r.out;
  const auto& o = cert["outliers"];
  const size_t n = o["outlier_frames"].get<size_t>();
  EXPECT_GE(n, 4u);
  EXPECT_LE(n, 25u);  // 0.4 % of about 2,400 frames
  EXPECT_EQ(o["pitch"]["outlier_frames"].get<size_t>() + o["yaw"]["outlier_frames"].get<size_t>(), n);
  std::map<std::string, nlohmann::json> by_id;
  for (const auto& c : cert["criteria"]) by_id[c["id"].get<std::string>()] = c;
  EXPECT_NEAR(by_id.at("outlier_frames")["measured"].get<double>(), std::max(o["pitch"]["share"].get<double>(),
                                                                                o["yaw"]["share"].get<double>()), 1e-12);
  for (const char* id : {"accuracy_3sigma_pitch", "accuracy_3sigma_yaw", "accuracy_worst_point_pitch",
                         "accuracy_worst_point_yaw", "accuracy_centre_pitch", "accuracy_centre_yaw"}) {
    EXPECT_LT(by_id.at(id)["measured"].get<double>(), 0.5) << id;
  }
  const fs::path run = cert["run"]["dir"].get<std::string>();
  const auto cal = nlohmann::json::parse(read_file(run / "calibration.json"));
  const std::string html = read_file(run / "report.html");
  const std::string text = read_file(run / "certificate.txt");
  EXPECT_EQ(html.find("differs from the residuals"), std::string::npos);
  for (const char* axis : {"pitch", "yaw"}) {
    const auto& res = cal["residuals"][axis];
    EXPECT_DOUBLE_EQ(by_id.at(std::string("residual_mean_") + axis)["measured"].get<double>(),
                     res["mean_abs_arcsec"].get<double>());
    EXPECT_DOUBLE_EQ(by_id.at(std::string("residual_max_") + axis)["measured"].get<double>(),
                     res["max_abs_arcsec"].get<double>());
    EXPECT_NE(html.find(fmt::format("{:.2f} &plusmn; {:.2f}</td><td>{:.2f}</td>", res["mean_abs_arcsec"].get<double>(),
                                    res["sd_arcsec"].get<double>(), res["max_abs_arcsec"].get<double>())),
              std::string::npos)
        << axis;
    EXPECT_LT(res["max_abs_arcsec"].get<double>(), 0.5) << axis;  // the glitches are not in the fit
  }
  // The certificate names the frames with their count; calibration.json and the report count the
  // calibration's own (a part of the same frames).
  EXPECT_NE(text.find(fmt::format("{} of {} dwell frames", n, o["frames"].get<size_t>())), std::string::npos) << text;
  EXPECT_NE(text.find("outlier_frames"), std::string::npos);
  const auto cal_n = cal["outliers"]["outlier_frames"].get<size_t>();
  EXPECT_LE(cal_n, n);
  EXPECT_NE(html.find(fmt::format("Outlier frames: {} of ", cal_n)), std::string::npos);
  // accept drew the page from the recording in memory; `report` draws it again from samples.csv:
  // the same page but for the time it was written.
  const CommandResult again = test::run_stand({"report", run.string()}, scratch_.path(), "glitch-report");
  ASSERT_EQ(again.code, 0) << again.err;
  const auto untimed = [](std::string h) {
    const auto at = h.find("Report written ");
    return at == std::string::npos ? h : h.erase(at, h.find(" by fpss-stand", at) - at);
  };
  EXPECT_EQ(untimed(read_file(run / "report.html")), untimed(html));
}

TEST_F(AcceptCli, BadTransferFunctionRegionFailsOnAccuracyOfThatAxis) {
  const fs::path truth = scratch_.path() / "ripple.json";
  save_coefficients(truth, rippled_truth(3.0));
  const CommandResult r = accept("--effect 'coefficients:file=" + truth.string() + "'");
  ASSERT_EQ(r.code, 3) << r.err << r.out;
  const auto f = failed(nlohmann::json::parse(r.out));
  EXPECT_TRUE(f.count("accuracy_3sigma_pitch")) << r.out;
  for (const auto& id : f) EXPECT_NE(id.find("pitch"), std::string::npos) << id;
  EXPECT_FALSE(f.count("jitter_3sigma_pitch"));
}

TEST_F(AcceptCli, RolledUnitFailsOnAccuracy) {
  const CommandResult r = accept("--effect boresight_roll:roll_arcsec=1800");
  ASSERT_EQ(r.code, 3) << r.err << r.out;
  const auto f = failed(nlohmann::json::parse(r.out));
  EXPECT_TRUE(f.count("accuracy_worst_point_pitch") && f.count("accuracy_worst_point_yaw")) << r.out;
  EXPECT_FALSE(f.count("jitter_3sigma_pitch") || f.count("jitter_3sigma_yaw") || f.count("sun_present")) << r.out;
}

TEST_F(AcceptCli, UnitBlindNearTheEdgeFailsOnSunPresence) {
  // The Sun is seen only within 0.39 deg: the calibration's 0.42 deg points give no valid frame.
  const fs::path bench = write("narrow.yaml", "sun_half_fov_arcsec: 1400\n");
  const CommandResult r = accept("--bench '" + bench.string() + "'");
  ASSERT_EQ(r.code, 3) << r.err << r.out;
  const auto cert = nlohmann::json::parse(r.out);
  EXPECT_TRUE(failed(cert).count("sun_present")) << r.out;
  EXPECT_EQ(cert["run"]["outcome"], "failed");
  EXPECT_NE(cert["run"]["reason"].get<std::string>().find("invalid frame"), std::string::npos);
  for (const auto& c : cert["criteria"]) {
    if (c["id"] == "sun_present") {
      EXPECT_LT(c["measured"].get<double>(), 1.0);
    }
  }
  SqliteCatalogue cat(Catalogue::default_path(runs()), Catalogue::Mode::read_only);
  ASSERT_EQ(cat.unit_acceptances("EMU-0001").size(), 1u);
  EXPECT_FALSE(cat.unit_acceptances("EMU-0001")[0].passed);
}

TEST_F(AcceptCli, RealBenchPathWithAStandFileAndTheUnitsSerial) {
  // A bench started on its own (as a real one would be), reached through a stand file.
  EmulatorLaunch l;
  l.exe = test::stand_binary();
  l.args = {"--speed", "40", "--seed", "5", "--unit-serial", "SN-0042"};
  EmulatorProcess emu(l);
  emu.start();
  const fs::path stand = write("stand.yaml", "stand: bench-under-test-7\n"
                                             "gimbal:\n  endpoint: " + emu.gimbal_endpoint() + "\n"
                                             "sensor:\n  endpoint: " + emu.sensor_endpoint() + "\n  sample_rate_hz: 50\n"
                                             "clock:\n  sync: shared\n  time_scale: 40\n");
  const std::string common = "accept --quiet --json --runs-dir '" + runs().string() + "' --stand '" + stand.string() + "'";
  // The wrong unit on the stand: bad input, nothing moved, nothing judged.
  CommandResult r = test::run_stand_shell(common + " --unit SN-0001", scratch_.path());
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("SN-0042"), std::string::npos) << r.err;
  r = test::run_stand_shell(common + " --unit SN-0042", scratch_.path());
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  const auto cert = nlohmann::json::parse(r.out);
  EXPECT_EQ(cert["unit"], "SN-0042");
  EXPECT_EQ(cert["stand"]["identity"], "bench-under-test-7");
  EXPECT_EQ(cert["verdict"], "pass");
  emu.stop();
}

TEST_F(AcceptCli, TwoAcceptancesAtOnceAndAKilledOneLeaveASoundCatalogue) {
  auto args = [&](const std::string& unit, const std::string& seed) {
    return std::vector<std::string>{"accept", "--emulate", "--quiet", "--speed", "40", "--json", "--runs-dir",
                                    runs().string(), "--unit", unit, "--seed", seed};
  };
  const fs::path dir = scratch_.path();
  test::Child a = test::start_stand(args("UNIT-A", "7"), dir, "a");
  test::Child b = test::start_stand(args("UNIT-B", "8"), dir, "b");
  test::Child c = test::start_stand(args("UNIT-C", "9"), dir, "c");
  // Kill C once its run is in the catalogue and has recorded points (the catalogue is shared).
  const bool c_running = test::wait_until(
      [&] {
        if (!fs::exists(Catalogue::default_path(runs()))) return false;
        try {
          SqliteCatalogue cat(Catalogue::default_path(runs()), Catalogue::Mode::read_only);
          bool running = false;
          for (const auto& r : cat.list_runs({.unit = "UNIT-C", .limit = 0})) {
            const fs::path points = fs::path(r.run_dir) / "points.jsonl";
            running = fs::exists(points) && fs::file_size(points) > 0;
          }
          return running;
        } catch (const std::exception&) {
          return false;  // the catalogue is being created by another process: look again
        }
      },
      120, std::chrono::milliseconds(50));
  ASSERT_TRUE(c_running) << read_file(dir / "c.err");
  ASSERT_EQ(::kill(c.pid(), SIGKILL), 0);
  EXPECT_EQ(c.wait(), 128 + SIGKILL);
  EXPECT_EQ(a.wait(), 0) << read_file(dir / "a.err");
  EXPECT_EQ(b.wait(), 0) << read_file(dir / "b.err");

  SqliteCatalogue cat(Catalogue::default_path(runs()), Catalogue::Mode::read_only);
  EXPECT_EQ(cat.integrity_check(), "ok");
  for (const char* unit : {"UNIT-A", "UNIT-B"}) {
    const auto acc = cat.unit_acceptances(unit);
    ASSERT_EQ(acc.size(), 1u) << unit;
    EXPECT_TRUE(acc[0].passed);
    EXPECT_EQ(cat.unit_history(unit).size(), 1u);
    const auto runs_of = cat.list_runs({.unit = unit, .limit = 0});
    ASSERT_EQ(runs_of.size(), 1u);
    EXPECT_EQ(runs_of[0].outcome, RunOutcome::completed);
  }
  // The killed one: its run stays "running" and is seen as stale; no verdict was recorded.
  const auto killed = cat.list_runs({.unit = "UNIT-C", .limit = 0});
  ASSERT_EQ(killed.size(), 1u);
  EXPECT_TRUE(killed[0].running());
  EXPECT_TRUE(killed[0].stale());
  EXPECT_TRUE(cat.unit_acceptances("UNIT-C").empty());
  // And the catalogue takes the next acceptance as usual.
  const CommandResult again = accept("--unit UNIT-C --seed 10");
  EXPECT_EQ(again.code, 0) << again.err;
  SqliteCatalogue after(Catalogue::default_path(runs()), Catalogue::Mode::read_only);
  EXPECT_EQ(after.unit_acceptances("UNIT-C").size(), 1u);
  EXPECT_EQ(after.integrity_check(), "ok");
}

// A decision near the limit, end to end. A good unit sends no outlier frame in its ~2,440 dwell
// frames: the share 0 has a binomial u of one frame's worth, 1/n, and U of about 0.0008. A stand
// policy of at most 1 in 2,500 (0.0004) lies within U of it: the simple rule passes the unit, the
// guarded rule cannot (the acceptance limit 0.0004 - U is below zero) and calls it conditional
// (exit 4, not accepted in the catalogue), and the certificate says why. Nothing here depends on
// the run's noise: the share is 0 and U follows from the count of frames.
TEST_F(AcceptCli, AValueWithinUOfItsLimitPassesSimpleAndIsConditionalGuarded) {
  std::string text = read_file(default_limits_path());
  const std::string from = "  outlier_frames_fraction:\n    value: 0.001";
  ASSERT_NE(text.find(from), std::string::npos);
  text.replace(text.find(from), from.size(), "  outlier_frames_fraction:\n    value: 0.0004");
  const fs::path simple = write("near_simple.yaml", text);
  const std::string rule = "decision_rule:\n  rule: simple\n";
  ASSERT_NE(text.find(rule), std::string::npos);
  text.replace(text.find(rule), rule.size(), "decision_rule:\n  rule: guarded\n  guard_multiple: 1.0\n");
  const fs::path guarded = write("near_guarded.yaml", text);

  const CommandResult s = accept("--seed 3 --unit NEAR-1 --limits '" + simple.string() + "'");
  ASSERT_EQ(s.code, 0) << s.err << s.out;
  const auto c1 = nlohmann::json::parse(s.out);
  EXPECT_EQ(c1["verdict"], "pass");
  EXPECT_EQ(c1["decision_rule"]["rule"], "simple");
  for (const auto& c : c1["criteria"]) {
    EXPECT_EQ(c["outcome"], "pass") << c.dump();
    EXPECT_EQ(c["acceptance_limit"], c["limit"]);  // simple: no guard band
    if (c["id"] == "outlier_frames") {
      EXPECT_EQ(c["measured"].get<double>(), 0.0);
      EXPECT_GT(c["expanded_uncertainty"].get<double>(), 0.0004) << c.dump();
      EXPECT_EQ(c["budget"].size(), 1u);
    }
  }

  const CommandResult g = accept("--seed 3 --unit NEAR-2 --limits '" + guarded.string() + "'");
  ASSERT_EQ(g.code, 4) << g.err << g.out;
  const auto c2 = nlohmann::json::parse(g.out);
  EXPECT_EQ(c2["verdict"], "conditional");
  EXPECT_FALSE(c2["passed"].get<bool>());
  EXPECT_TRUE(c2["failed"].empty());
  EXPECT_EQ(c2["conditional"], nlohmann::json::array({"outlier_frames"})) << g.out;
  for (const auto& c : c2["criteria"]) {
    if (c["id"] != "outlier_frames") continue;
    EXPECT_EQ(c["outcome"], "conditional");
    EXPECT_NEAR(c["acceptance_limit"].get<double>(), 0.0004 - c["expanded_uncertainty"].get<double>(), 1e-15);
    EXPECT_NE(c["outcome_reason"].get<std::string>().find("where simple acceptance would pass it"), std::string::npos);
  }
  const fs::path dir = c2["run"]["dir"].get<std::string>();
  const std::string cert = read_file(dir / "certificate.txt");
  EXPECT_NE(cert.find("Verdict:    CONDITIONAL"), std::string::npos) << cert;
  EXPECT_NE(cert.find("Decision rule: guarded acceptance, guard band w = 1.0 x U (ILAC-G8)"), std::string::npos) << cert;
  EXPECT_NE(cert.find("Where this rule decides otherwise than simple acceptance:\n- outlier_frames: the value 0 (fraction) is within"),
            std::string::npos) << cert;
  EXPECT_EQ(nlohmann::json::parse(read_file(dir / "run.json"))["acceptance"]["verdict"], "conditional");
  const std::string page = read_file(dir / "report.html");
  EXPECT_NE(page.find("Acceptance: CONDITIONAL"), std::string::npos);
  EXPECT_NE(page.find("class=\"verdict conditional\""), std::string::npos);
  SqliteCatalogue cat(Catalogue::default_path(runs()), Catalogue::Mode::read_only);
  const auto acc = cat.unit_acceptances("NEAR-2");
  ASSERT_EQ(acc.size(), 1u);
  EXPECT_FALSE(acc[0].passed);
  EXPECT_EQ(acc[0].certificate["verdict"], "conditional");
}

TEST_F(AcceptCli, BadInputExitsTwoBeforeAnythingMoves) {
  std::string text = read_file(default_limits_path());
  text.replace(text.find("value: 3.0"), 10, "value: -3");
  const fs::path bad_limits = write("limits.yaml", text);
  CommandResult r = accept("--limits '" + bad_limits.string() + "'");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("limits.yaml:"), std::string::npos) << r.err;
  r = accept("--procedure '" + test::shipped_procedure("discrete_grid.yaml") + "'");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("not an acceptance procedure"), std::string::npos) << r.err;
  r = accept("--effect wobble:amount=3");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("wobble"), std::string::npos) << r.err;
  r = test::run_stand_shell("accept --stand '" + write("s.yaml", "stand: x\n").string() + "'", scratch_.path());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--unit"), std::string::npos) << r.err;
  r = test::run_stand_shell("accept --stand '" + (scratch_.path() / "s.yaml").string() + "' --unit U --seed 3",
                            scratch_.path());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--emulate"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(runs()) && !fs::is_empty(runs())) << "a run folder was made";
}

}  // namespace
}  // namespace fpss
