// Whole text files from hostile places: what is not a regular file, files too large, planted
// symlinks, outputs that are inputs, missing / read-only folders and a full disk.
#include "base/text_file.h"

#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "base/errors.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

std::vector<std::string> names_in(const fs::path& dir) {
  std::vector<std::string> v;
  for (const auto& e : fs::directory_iterator(dir)) v.push_back(e.path().filename().string());
  std::sort(v.begin(), v.end());
  return v;
}

TEST(ReadTextFile, RefusesWhatIsNotARegularFileBeforeReading) {
  TempDir d;
  const fs::path fifo = d / "data.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const fs::path& p : {d.path(), fs::path("/dev/zero"), fifo}) {
    SCOPED_TRACE(p.string());
    // A FIFO with no writer would block an open for reading; /dev/zero would grow without bound.
    const std::string m = test::error_of<InputError>([&] { read_text_file(p, "samples file"); });
    EXPECT_NE(m.find(p.string() + ": not a regular file"), std::string::npos) << m;
    EXPECT_NE(m.find("samples file"), std::string::npos) << m;
  }
  const std::string m = test::error_of<InputError>([&] { read_text_file(d / "nope.csv", "samples file"); });
  EXPECT_NE(m.find("nope.csv: cannot open samples file: No such file"), std::string::npos) << m;
}

TEST(ReadTextFile, SizeLimit) {
  TempDir d;
  const fs::path p = d.write("big.yaml", std::string(1000, 'x'));
  EXPECT_EQ(read_text_file(p, "procedure file", 1000).size(), 1000u);
  const std::string m = test::error_of<InputError>([&] { read_text_file(p, "procedure file", 999); });
  EXPECT_NE(m.find("big.yaml: 1000 bytes, more than the 999 bytes a procedure file may have"), std::string::npos) << m;
}

TEST(WriteTextAtomic, NeverFollowsASymlinkPlantedAtTheTemporaryName) {
  TempDir d;
  const fs::path victim = d.write("victim.txt", "precious\n");
  const fs::path out = d / "out.json";
  // The old fixed temporary name, and the hidden prefix the new one uses, both planted.
  fs::create_symlink(victim, d / "out.json.tmp");
  fs::create_symlink(victim, d / ".out.json.tmp-");
  write_text_atomic(out, "{\"new\": 1}\n");
  EXPECT_EQ(test::read_file(out), "{\"new\": 1}\n");
  EXPECT_EQ(test::read_file(victim), "precious\n");
  EXPECT_TRUE(fs::is_symlink(d / "out.json.tmp"));
  EXPECT_EQ(names_in(d.path()), (std::vector<std::string>{".out.json.tmp-", "out.json", "out.json.tmp", "victim.txt"}));
}

TEST(WriteTextAtomic, TemporaryNamesAreUnpredictable) {
  TempDir d;
  AtomicFile a(d / "x.csv"), b(d / "x.csv");
  EXPECT_NE(a.temp_path(), b.temp_path());
  EXPECT_EQ(a.temp_path().parent_path(), d.path());
  EXPECT_EQ(a.temp_path().filename().string().rfind(".x.csv.tmp-", 0), 0u) << a.temp_path();
  EXPECT_EQ(a.temp_path().filename().string().size(), std::string(".x.csv.tmp-").size() + 16);
}

TEST(WriteTextAtomic, AbandonedFileLeavesTargetAndNoTemporary) {
  TempDir d;
  const fs::path out = d.write("out.csv", "old\n");
  {
    AtomicFile f(out);
    f.write("new, half written");
    EXPECT_TRUE(fs::exists(f.temp_path()));
  }  // destroyed without commit, as when an exception unwinds
  EXPECT_EQ(test::read_file(out), "old\n");
  EXPECT_EQ(names_in(d.path()), std::vector<std::string>{"out.csv"});
}

TEST(WriteTextAtomic, FullDiskFailsWithoutPartialOrTemporaryFile) {
  test::SmallTmpfs disk("64k");
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here (needs root)";
  const fs::path out = disk / "cal.json";
  write_text_atomic(out, "old\n");
  const std::string m = test::error_of<std::runtime_error>([&] { write_text_atomic(out, std::string(256 * 1024, 'x')); });
  EXPECT_NE(m.find("cal.json: write failed: No space left on device"), std::string::npos) << m;
  EXPECT_EQ(test::read_file(out), "old\n");
  EXPECT_EQ(names_in(disk.path()), std::vector<std::string>{"cal.json"});
}

TEST(CheckOutputPath, TheSameFileAsAnInputInAnySpelling) {
  TempDir d;
  fs::create_directory(d / "sub");
  const fs::path in = d.write("data.csv", "x\n");
  fs::create_hard_link(in, d / "hard.csv");
  fs::create_symlink(in, d / "sym.csv");
  for (const fs::path& out : {in, d / "sub" / ".." / "data.csv", d / "hard.csv", d / "sym.csv"}) {
    SCOPED_TRACE(out.string());
    const std::string m = test::error_of<InputError>([&] { check_output_path(out, {in}); });
    EXPECT_NE(m.find("--out " + out.string() + ": is the same file as the input " + in.string()), std::string::npos) << m;
  }
  // Relative spelling from the current folder.
  const fs::path cwd = fs::current_path();
  fs::current_path(d.path());
  const std::string m = test::error_of<InputError>([&] { check_output_path("./sub/../data.csv", {in}); });
  fs::current_path(cwd);
  EXPECT_NE(m.find("is the same file as the input"), std::string::npos) << m;
  EXPECT_NO_THROW(check_output_path(d / "new.json", {in, d / "missing-input.json"}));
  EXPECT_NO_THROW(check_output_path(d / "sub" / "other.csv", {in}));
  EXPECT_EQ(test::read_file(in), "x\n");
}

TEST(CheckOutputPath, MissingFolderFolderAsFileAndReadOnlyFolder) {
  TempDir d;
  std::string m = test::error_of<InputError>([&] { check_output_path(d / "no" / "such" / "out.csv", {}); });
  EXPECT_NE(m.find("its folder " + (d / "no" / "such").string() + " does not exist"), std::string::npos) << m;
  m = test::error_of<InputError>([&] { check_output_path(d.path(), {}, "--report"); });
  EXPECT_NE(m.find("--report " + d.path().string() + ": is a folder"), std::string::npos) << m;
  const fs::path file = d.write("plain", "");
  m = test::error_of<InputError>([&] { check_output_path(file / "out.csv", {}); });
  EXPECT_NE(m.find("is not a folder"), std::string::npos) << m;

  test::SmallTmpfs ro("16k", /*read_only=*/true);
  if (!ro.mounted()) GTEST_SKIP() << "cannot mount a read-only tmpfs here (needs root)";
  m = test::error_of<InputError>([&] { check_output_path(ro / "out.csv", {}); });
  EXPECT_NE(m.find("is not writable (Read-only file system)"), std::string::npos) << m;
}

}  // namespace
}  // namespace fpss
