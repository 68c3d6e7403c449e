// Every command that reads a coefficient file or a recording, or writes a file, against hostile
// files: deep or duplicated JSON, absurd numbers, what is not a regular file, an output that is an
// input, a missing or read-only folder, a planted symlink and a full disk. Each case checks the exit
// code, the message (file and key) and that nothing was lost or overwritten.
#include <sys/stat.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using test::CommandResult;

const std::string kGood = std::string(FPSS_SOURCE_DIR) + "/calib/data/published/a-6-fpss1.json";

class HostileFiles : public ::testing::Test {
 protected:
  CommandResult run(const std::vector<std::string>& args, const std::string& tag = "cli") const {
    return test::run_stand(args, dir_.path(), tag, 120);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string write(const std::string& name, const std::string& text) const { return dir_.write(name, text).string(); }
  std::vector<std::string> names() const {
    std::vector<std::string> v;
    for (const auto& e : fs::directory_iterator(dir_.path())) v.push_back(e.path().filename().string());
    std::sort(v.begin(), v.end());
    return v;
  }
  // A small simulated recording (the default grid), made once per test that needs one.
  std::string recording(const std::string& name = "rec.csv") const {
    const CommandResult r = run({"simulate", "--out", path(name), "--samples-per-dwell", "4"}, "sim");
    EXPECT_EQ(r.code, 0) << r.err;
    return path(name);
  }

  test::TempDir dir_{"hostile"};
};

TEST_F(HostileFiles, EveryCoefficientReaderRefusesDeepDuplicateAndAbsurdJson) {
  const std::string deep = write("deep.json", std::string(200000, '[') + std::string(200000, ']'));
  const std::string dup = write("dup.json", R"({"alpha": [0,5e-7,0,0,0,0,0,0], "alpha": [0,5e-7,0,0,0,0,0,0], "beta": [0,5e-7,0,0,0,0,0,0]})");
  const std::string huge = write("huge.json", R"({"alpha": [0,5e-7,0,0,1e308,0,0,0], "beta": [0,5e-7,0,0,0,0,0,0]})");
  const std::string data = write("d.csv", "time_s,phase,step,ref_pitch_arcsec,ref_yaw_arcsec,counts_alpha,counts_beta\n0,null,1,0,0,0,0\n");
  using V = std::vector<std::string>;
  const std::vector<std::pair<const char*, V (*)(const std::string&, const std::string&, const std::string&)>> commands = {
      {"angles", [](const std::string& f, const std::string&, const std::string&) { return V{"angles", "--model", f, "--alpha", "0", "--beta", "0"}; }},
      {"compare", [](const std::string& f, const std::string&, const std::string&) { return V{"compare", f, "a-6-fpss1"}; }},
      {"calibrate --init", [](const std::string& f, const std::string& d, const std::string& dir) { return V{"calibrate", "--data", d, "--out", dir + "/cal.json", "--init", f}; }},
      {"import", [](const std::string& f, const std::string&, const std::string& dir) { return V{"import", f, "--unit", "U1", "--date", "2024-01-01", "--runs-dir", dir + "/runs"}; }},
      {"diagnose --model", [](const std::string& f, const std::string& d, const std::string& dir) { return V{"diagnose", "--model", f, "--data", d, "--out", dir + "/gap.json"}; }},
      {"emulate --truth", [](const std::string& f, const std::string&, const std::string&) { return V{"emulate", "--truth", f, "--modbus-port", "0"}; }},
      {"accept --truth", [](const std::string& f, const std::string&, const std::string& dir) { return V{"accept", "--emulate", "--truth", f, "--runs-dir", dir + "/runs"}; }},
  };
  for (const auto& [name, args] : commands) {
    for (const auto& [file, expect] : {std::pair{deep, std::string("deep.json:1:65: nested deeper than 64 levels")},
                                       std::pair{dup, std::string("dup.json:1:")},
                                       std::pair{dup, std::string("key \"alpha\" given twice")},
                                       std::pair{huge, std::string("huge.json: \"alpha\"[4] (C5) = 1e+308 is beyond")}}) {
      SCOPED_TRACE(std::string(name) + " " + file);
      const CommandResult r = run(args(file, data, dir_.path().string()));
      EXPECT_EQ(r.code, 2) << r.err;
      EXPECT_NE(r.err.find(expect), std::string::npos) << r.err;
    }
  }
  // Nothing written by any of them: no coefficient file, no GAP.json, no runs folder.
  EXPECT_EQ(names(), (std::vector<std::string>{"cli.err", "cli.out", "d.csv", "deep.json", "dup.json", "huge.json"}));
}

TEST_F(HostileFiles, ProceduresBeyondTheLimitsExitTwoBeforeAnythingRuns) {
  const std::string head = "name: g\nsteps:\n  - null_offset_grid:\n      axes: [pitch, yaw]\n      extent_deg: 0.42\n";
  const std::string big = write("big.yaml", head + "      step_deg: 1e-5\n      frames: 1\n");
  const std::string slow = write("slow.yaml", head + "      step_deg: 0.03\n      frames: 1\n      settle_s: 1e308\n");
  CommandResult r = run({"run", big, "--emulate", "--dry-run", "--runs-dir", path("runs")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("big.yaml:4:7: step 1 (null_offset_grid): extent 1512 arcsec in steps of"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("a plan may have at most 100000"), std::string::npos) << r.err;
  r = run({"run", slow, "--emulate", "--dry-run", "--runs-dir", path("runs")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("slow.yaml:8:17: step 1 (null_offset_grid): field settle_s: 1e308 is outside"), std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(path("runs")));  // nothing started, nothing recorded
}

TEST_F(HostileFiles, AnglesRefusesCountsThatAreNotFiniteNumbers) {
  for (const std::string v : {"nan", "inf", "-inf", "1e308"}) {
    SCOPED_TRACE(v);
    const CommandResult r = run({"angles", "--model", kGood, "--alpha", v, "--beta", "0"});
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("--alpha"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("expected counts, a finite number"), std::string::npos) << r.err;
    EXPECT_EQ(r.out.find("null"), std::string::npos) << r.out;
  }
  const CommandResult ok = run({"angles", "--model", kGood, "--alpha", "100.5", "--beta", "-3"});
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_EQ(ok.out.find("null"), std::string::npos) << ok.out;
}

TEST_F(HostileFiles, RecordingsThatAreNotRegularFilesOrOverflow) {
  const std::string fifo = path("rec.fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& p : {fifo, std::string("/dev/zero"), dir_.path().string()}) {
    SCOPED_TRACE(p);
    const CommandResult r = run({"calibrate", "--data", p, "--out", path("cal.json")});
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find(p + ": not a regular file"), std::string::npos) << r.err;
  }
  const std::string h = "\xEF\xBB\xBFtime_s,phase,step,ref_pitch_arcsec,ref_yaw_arcsec,counts_alpha,counts_beta\n";
  const std::string big = write("big.csv", h + "0,null,1,0,0,0,0\n1,offset,2,1e308,0,5,5\n");
  CommandResult r = run({"calibrate", "--data", big, "--out", path("cal.json")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("big.csv:3: column \"ref_pitch_arcsec\": 1e308 is beyond"), std::string::npos) << r.err;
  const std::string over = write("over.csv", h + "0,null,1,0,0,1e400,0\n");
  r = run({"diagnose", "--model", kGood, "--data", over, "--out", path("gap.json")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("over.csv:2: column \"counts_alpha\""), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("cal.json")));
  EXPECT_FALSE(fs::exists(path("gap.json")));
}

TEST_F(HostileFiles, AnOutputThatIsAnInputInAnySpellingIsRefusedAndKept) {
  const std::string data = recording();
  const std::string before = test::read_file(data);
  fs::create_directory(path("sub"));
  fs::create_hard_link(data, path("hard.csv"));
  for (const std::string& out : {data, path("sub/../rec.csv"), path("hard.csv")}) {
    SCOPED_TRACE(out);
    CommandResult r = run({"calibrate", "--data", data, "--out", out});
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("is the same file as the input"), std::string::npos) << r.err;
    r = run({"diagnose", "--model", kGood, "--data", data, "--out", out});
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("is the same file as the input"), std::string::npos) << r.err;
  }
  const std::string model = path("model.json");
  fs::copy_file(kGood, model);
  CommandResult r = run({"simulate", "--truth", model, "--out", model});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--out " + model + ": is the same file as the input " + model), std::string::npos) << r.err;
  r = run({"diagnose", "--model", model, "--data", data, "--out", path("gap.json"), "--report", model});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--report " + model + ": is the same file as the input"), std::string::npos) << r.err;
  // --emit-bench is an output as the others are; so is the refitted transfer function it writes
  // beside itself (NAME.coefficients.json), which must not be the model it was diagnosed against.
  r = run({"diagnose", "--model", model, "--data", data, "--out", path("gap.json"), "--emit-bench", data});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--emit-bench " + data + ": is the same file as the input"), std::string::npos) << r.err;
  const std::string model_coefficients = path("m.coefficients.json");
  fs::copy_file(kGood, model_coefficients);
  r = run({"diagnose", "--model", model_coefficients, "--data", data, "--out", path("gap.json"), "--emit-bench",
           path("m.yaml")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--emit-bench " + model_coefficients + ": is the same file as the input"), std::string::npos)
      << r.err;
  EXPECT_EQ(test::read_file(model_coefficients), test::read_file(kGood));
  // ...nor another output of the same command.
  r = run({"diagnose", "--model", model, "--data", data, "--out", path("n.coefficients.json"), "--emit-bench",
           path("n.yaml")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--emit-bench " + path("n.coefficients.json") + ": the same file as --out"), std::string::npos)
      << r.err;
  // Two outputs naming one file, before either exists.
  r = run({"diagnose", "--model", model, "--data", data, "--out", path("gap.json"), "--report", path("sub/../gap.json")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--report " + path("sub/../gap.json") + ": the same file as --out"), std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(path("gap.json")));
  r = run({"compare", model, "a-7-fpss1", "--plot", path("model.svg")});  // model.dat, model.gp: free
  EXPECT_EQ(r.code == 0 || r.code == 1, true) << r.err;                   // 1 only when gnuplot is missing
  r = run({"compare", data, "a-7-fpss1", "--plot", path("rec.svg")});     // rec.dat is free, but not an input...
  EXPECT_EQ(r.code, 2);                                                    // ...rec.csv is not a coefficient file
  // import --db naming the coefficient file itself.
  r = run({"import", model, "--unit", "U1", "--date", "2024-01-01", "--db", path("sub/../model.json")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--db " + path("sub/../model.json") + ": is the same file as the input"), std::string::npos)
      << r.err;
  EXPECT_EQ(test::read_file(data), before);
  EXPECT_EQ(test::read_file(model), test::read_file(kGood));
}

TEST_F(HostileFiles, MissingOrReadOnlyFolderIsExitTwoBeforeAnyWork) {
  const std::string data = recording();
  CommandResult r = run({"simulate", "--out", path("no/such/rec.csv")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--out " + path("no/such/rec.csv") + ": its folder " + path("no/such") + " does not exist"),
            std::string::npos) << r.err;
  r = run({"calibrate", "--data", data, "--out", path("missing/cal.json")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("does not exist"), std::string::npos) << r.err;
  r = run({"diagnose", "--model", kGood, "--data", data, "--out", path("gap.json"), "--report", path("none/gap.html")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--report " + path("none/gap.html")), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("gap.json")));  // checked before anything was written

  test::SmallTmpfs ro("16k", /*read_only=*/true);
  if (!ro.mounted()) GTEST_SKIP() << "cannot mount a read-only tmpfs here (needs root)";
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"simulate", "--out", (ro / "rec.csv").string()},
        std::vector<std::string>{"calibrate", "--data", data, "--out", (ro / "cal.json").string()},
        std::vector<std::string>{"diagnose", "--model", kGood, "--data", data, "--out", (ro / "gap.json").string()},
        std::vector<std::string>{"compare", "a-6-fpss1", "a-7-fpss1", "--plot", (ro / "p.svg").string()}}) {
    SCOPED_TRACE(args[0]);
    r = run(args);
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("is not writable (Read-only file system)"), std::string::npos) << r.err;
  }
}

TEST_F(HostileFiles, SimulateOnAFullDiskLeavesNoTruncatedCsv) {
  test::SmallTmpfs disk("64k");
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (needs root)";
  const fs::path out = disk / "rec.csv";
  test::write_file(out, "old recording\n");
  const CommandResult r = run({"simulate", "--out", out.string(), "--samples-per-dwell", "200"});  // ~1 MB
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("rec.csv: write failed: No space left on device"), std::string::npos) << r.err;
  EXPECT_EQ(test::read_file(out), "old recording\n");
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(disk.path())) left.push_back(e.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{"rec.csv"});  // no temporary file either
}

TEST_F(HostileFiles, APlantedSymlinkAtTheTemporaryNameIsNeverFollowed) {
  const std::string victim = write("victim.txt", "precious\n");
  fs::create_symlink(victim, path("rec.csv.tmp"));
  fs::create_symlink(victim, path("cal.json.tmp"));
  const std::string data = recording();
  const CommandResult r = run({"calibrate", "--data", data, "--out", path("cal.json")});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(test::read_file(victim), "precious\n");
  EXPECT_TRUE(fs::is_symlink(path("rec.csv.tmp")));
  EXPECT_TRUE(fs::is_symlink(path("cal.json.tmp")));
  EXPECT_NE(test::read_file(path("cal.json")).find("\"alpha\""), std::string::npos);
}

}  // namespace
}  // namespace fpss
