// A run folder end to end: one owner at a time, one run whatever the spelling of its path, a catalogue
// that cannot record ends in exit 1 with the folder complete and `catalogue rebuild` restoring the
// index (the run's operator too), and events.jsonl telling the run as it happened.
#include <fmt/format.h>

#include <unistd.h>

#include <SQLiteCpp/SQLiteCpp.h>

#include <sstream>

#include "procedures/events.h"
#include "stand/catalogue/run_file.h"
#include "tests/stand/run_helpers.h"

namespace fpss {
namespace {

using namespace runtest;
using test::run_stand;
using test::TempDir;

const char* kSmallGrid =
    "name: small_grid\nsteps:\n  - home\n"
    "  - null_offset_grid: {extent_deg: 0.3, step_deg: 0.05, frames: 5, settle_s: 0.2}\n"
    "  - calibrate: {}\n";

std::vector<nlohmann::json> jsonl(const fs::path& p) {
  std::vector<nlohmann::json> out;
  std::istringstream in(test::read_file(p));
  for (std::string line; std::getline(in, line);) out.push_back(nlohmann::json::parse(line));
  return out;
}

TEST(RunFolder, ASecondOwnerIsRefusedAndEverySpellingReachesTheSameRun) {
  TempDir tmp("run-lock");
  const auto runs = tmp / "runs";
  test::Child c = test::start_stand(
      {"run", proc("discrete_grid.yaml"), "--emulate", "--runs-dir", runs.string(), "--quiet"}, tmp.path(), "first");
  ASSERT_TRUE(test::wait_until([&] { return test::journaled_points(runs) >= 3; }, 60, std::chrono::milliseconds(20)));
  const fs::path run = only_run(runs);
  fs::create_directory_symlink(run, tmp / "link");
  // While it runs: a resume through a symlink and one with a trailing slash are both refused.
  for (const std::string& spelling : {(tmp / "link").string(), run.string() + "/"}) {
    const auto r = run_stand({"run", "--resume", spelling, "--quiet"}, tmp.path(), "second");
    EXPECT_EQ(r.code, 1) << spelling << ": " << r.err;
    EXPECT_NE(r.err.find(fmt::format("pid {}", c.pid())), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("in use"), std::string::npos) << r.err;
  }
  c.signal(SIGTERM);
  ASSERT_EQ(c.wait(60), 1);
  EXPECT_EQ(run_json(run)["sessions"].size(), 1u);  // the refused ones wrote nothing
  // Resumed as tab completion gives it, relative (to this process's folder, which the child
  // shares) with a trailing slash: the same run, the runs folder's catalogue, no stray catalogue
  // inside the run folder.
  const std::string relative = fs::relative(run, fs::current_path()).string() + "/";
  const auto r = run_stand({"run", "--resume", relative, "--quiet"}, tmp.path(), "resume");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_FALSE(fs::exists(run / "stand.db"));
  EXPECT_EQ(run_json(run)["outcome"], "completed");
  SqliteCatalogue cat(runs / "stand.db", Catalogue::Mode::read_only);
  EXPECT_EQ(cat.find_run(run_id_of(run))->outcome, RunOutcome::completed);
  EXPECT_EQ(cat.run_calibrations(run_id_of(run)).size(), 1u);
}

TEST(RunFolder, ACatalogueThatCannotRecordExitsOneThenRebuildIndexesTheFolder) {
  TempDir tmp("run-catalogue");
  const auto runs = tmp / "runs";
  test::write_file(tmp / "grid.yaml", kSmallGrid);
  test::write_file(tmp / "not-a-folder", "a file where the catalogue's folder should be\n");
  const fs::path bad_catalogue = tmp / "not-a-folder" / "stand.db";
  const auto r = run_stand({"run", (tmp / "grid.yaml").string(), "--emulate", "--runs-dir", runs.string(),
                            "--catalogue", bad_catalogue.string(), "--operator", "T. Tester", "--quiet"},
                           tmp.path(), "run");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("catalogue"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("catalogue rebuild"), std::string::npos) << r.err;
  const fs::path run = only_run(runs);
  const auto doc = run_json(run);
  EXPECT_EQ(doc["outcome"], "completed");
  EXPECT_EQ(doc["stop_cause"], "none");
  EXPECT_TRUE(fs::exists(run / "calibration.json"));
  const size_t points = RunRecorder::read_journal(run / "points.jsonl").size();
  EXPECT_EQ(static_cast<int64_t>(points), doc["points"]["total"].get<int64_t>());

  // events.jsonl: one ordered story of the run.
  const auto events = jsonl(run / "events.jsonl");
  ASSERT_GE(events.size(), 2u);
  EXPECT_EQ(events.front()["type"], "run_started");
  EXPECT_EQ(events.back()["type"], "run_stopped");
  EXPECT_EQ(events.back()["cause"], "none");
  size_t done = 0;
  int64_t last_point = 0;
  for (const auto& e : events) {
    if (e["type"] != "point_done") continue;
    ++done;
    EXPECT_EQ(e["point"].get<int64_t>(), last_point + 1);  // 1-based, in order
    last_point = e["point"].get<int64_t>();
  }
  EXPECT_EQ(done, points);

  // The finished run replayed from its events.jsonl drives a summary as the live run did.
  EventBus bus;
  size_t replayed_done = 0;
  std::optional<RunStopped> stopped;
  std::optional<RunStarted> started;
  bus.subscribe([&](const Event& e) {
    replayed_done += std::holds_alternative<PointDone>(e);
    if (const auto* s = std::get_if<RunStopped>(&e)) stopped = *s;
    if (const auto* s = std::get_if<RunStarted>(&e)) started = *s;
  });
  const ReplayCount c = replay_events(run / "events.jsonl", bus);
  EXPECT_EQ(replayed_done, points);
  EXPECT_GE(c.events, 2 * points + 2);
  ASSERT_TRUE(started);
  EXPECT_EQ(static_cast<int64_t>(started->points_total), doc["points"]["total"].get<int64_t>());
  ASSERT_TRUE(stopped);
  EXPECT_EQ(to_string(stopped->outcome), doc["outcome"].get<std::string>());
  EXPECT_EQ(to_string(stopped->cause), doc["stop_cause"].get<std::string>());
  EXPECT_EQ(stopped->points_done, static_cast<int64_t>(points));
  EXPECT_EQ(stopped->safe_state, doc["safe_state"].get<bool>());
  // run.json read as its one type and written again: the same bytes.
  const RunFile rf = read_run_file(run);
  EXPECT_EQ(to_json(rf).dump(2) + "\n", test::read_file(run / "run.json"));
  EXPECT_EQ(rf.stop_cause, StopCause::none);
  EXPECT_EQ(rf.points.completed, static_cast<int64_t>(points));

  // Nothing recorded on disk is lost to the index: rebuild, twice (the second adds nothing).
  auto rb = run_stand({"catalogue", "rebuild", "--runs-dir", runs.string(), "--json"}, tmp.path(), "rebuild");
  ASSERT_EQ(rb.code, 0) << rb.err;
  auto j = nlohmann::json::parse(rb.out);
  EXPECT_EQ(j["runs_added"], 1);
  EXPECT_EQ(j["calibrations_added"], 1);
  rb = run_stand({"catalogue", "rebuild", "--runs-dir", runs.string(), "--json"}, tmp.path(), "rebuild2");
  ASSERT_EQ(rb.code, 0) << rb.err;
  j = nlohmann::json::parse(rb.out);
  EXPECT_EQ(j["runs_added"], 0);
  EXPECT_EQ(j["calibrations_added"], 0);
  EXPECT_EQ(j["operators_named"], 0);
  {
    SqliteCatalogue cat(runs / "stand.db", Catalogue::Mode::read_only);
    const auto rec = cat.find_run(run_id_of(run));
    ASSERT_TRUE(rec);
    EXPECT_EQ(rec->outcome, RunOutcome::completed);
    EXPECT_EQ(rec->operator_name, "T. Tester");  // run.json's operator
    ASSERT_EQ(cat.run_calibrations(run_id_of(run)).size(), 1u);
    EXPECT_EQ(cat.run_calibrations(run_id_of(run))[0].operator_name, "T. Tester");
  }
  // A catalogue that indexed the run before it kept operators (schema version 2, migrated: every
  // operator ''): a rebuild names the run's operator, on the run and on its calibration.
  {
    SQLite::Database d(runs / "stand.db", SQLite::OPEN_READWRITE);
    d.exec("UPDATE runs SET operator = ''; UPDATE calibrations SET operator = ''");
  }
  rb = run_stand({"catalogue", "rebuild", "--runs-dir", runs.string(), "--json"}, tmp.path(), "rebuild3");
  ASSERT_EQ(rb.code, 0) << rb.err;
  j = nlohmann::json::parse(rb.out);
  EXPECT_EQ(j["operators_named"], 1);
  EXPECT_EQ(j["calibrations_added"], 0);
  SqliteCatalogue cat(runs / "stand.db", Catalogue::Mode::read_only);
  EXPECT_EQ(cat.find_run(run_id_of(run))->operator_name, "T. Tester");
  EXPECT_EQ(cat.run_calibrations(run_id_of(run)).at(0).operator_name, "T. Tester");
}

}  // namespace
}  // namespace fpss
