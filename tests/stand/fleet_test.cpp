// A fleet of emulated stands on one real PostgreSQL server (tests/support/pg_server.h), through the
// fpss-stand binary: four stands accepting five units each at once, one killed mid-acceptance; a
// unit calibrated on one stand and accepted on another; the database going away mid-run.
#include <gtest/gtest.h>
#include <signal.h>

#include <fmt/format.h>

#include <future>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include <nlohmann/json.hpp>

#include "stand/catalogue/catalogue.h"
#include "tests/support/pg_server.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;
using test::CommandResult;

// The emulator runs the bench clock this much faster than real time: the acceptances take seconds.
constexpr const char* kSpeed = "100";

struct Stand {
  std::string name;
  fs::path dir, runs, file;
};

Stand make_stand(const fs::path& root, const std::string& name, const std::string& url) {
  Stand s{name, root / name, root / name / "runs", root / name / "stand.yaml"};
  fs::create_directories(s.runs);
  // The catalogue comes from the stand file: the way a stand of a fleet is set up (docs/fleet.md).
  test::write_file(s.file, fmt::format("stand: {}\ncatalogue: {}\ngimbal:\n  endpoint: modbus-tcp:127.0.0.1:1\n"
                                       "sensor:\n  endpoint: serial:/dev/null:115200\n",
                                       name, url));
  return s;
}

std::vector<std::string> accept_args(const Stand& s, const std::string& unit, int seed) {
  return {"accept", "--emulate", "--quiet", "--json", "--speed", kSpeed, "--runs-dir", s.runs.string(), "--stand",
          s.file.string(), "--unit", unit, "--seed", std::to_string(seed)};
}

// True once the catalogue holds a run of `unit` whose folder has recorded points.
bool has_recorded_points(const std::string& url, const std::string& unit) {
  try {
    const auto cat = open_catalogue(url, Catalogue::Mode::read_only);
    for (const auto& r : cat->list_runs({.unit = unit, .limit = 0})) {
      const fs::path points = fs::path(r.run_dir) / "points.jsonl";
      if (fs::exists(points) && fs::file_size(points) > 0) return true;
    }
  } catch (const std::exception&) {
  }
  return false;
}

bool has_passed_acceptance(const std::string& url, const std::string& unit) {
  try {
    for (const auto& a : open_catalogue(url, Catalogue::Mode::read_only)->unit_acceptances(unit)) {
      if (a.passed) return true;
    }
  } catch (const std::exception&) {
  }
  return false;
}

TEST(Fleet, FourStandsAcceptTwentyUnitsIntoOneDatabaseWithOneKilled) {
  test::PgServer pg;
  const std::string url = pg.create_database("fleet");
  test::TempDir tmp;
  std::vector<Stand> stands;
  for (const char* n : {"stand-A", "stand-B", "stand-C", "stand-D"}) stands.push_back(make_stand(tmp.path(), n, url));
  // Units (serial, seed): the shared unit is calibrated and accepted on A first, then on B.
  const std::string shared = "FLEET-SHARED";
  std::map<std::string, std::vector<std::pair<std::string, int>>> plan;
  for (int s = 0; s < 4; ++s) {
    for (int u = 0; u < 5; ++u) {
      plan[stands[s].name].emplace_back(fmt::format("FLEET-{}{}", "ABCD"[s], u + 1), 100 + 10 * s + u);
    }
  }
  plan["stand-A"][0] = {shared, 77};
  plan["stand-B"][4] = {shared, 77};  // the same unit (same seed: the same sensor)
  const std::string killed_unit = plan["stand-D"][2].first;

  std::map<std::string, std::vector<CommandResult>> results;
  std::mutex m;
  // A's exit code for the shared unit, set when that acceptance has ended: B's reference is then in the
  // catalogue. B waits for the event itself, not for a time, however loaded the machine.
  std::promise<int> shared_on_a;
  const std::shared_future<int> shared_on_a_done = shared_on_a.get_future().share();
  std::vector<std::thread> threads;
  for (const auto& st : stands) {
    threads.emplace_back([&, st] {
      int i = 0;
      for (const auto& [unit, seed] : plan[st.name]) {
        if (st.name == "stand-B" && unit == shared) {
          // B accepts the shared unit once A's acceptance of it has ended and passed.
          const bool came = shared_on_a_done.wait_for(std::chrono::seconds(1800)) == std::future_status::ready;
          EXPECT_TRUE(came) << "stand A never finished the shared unit";
          if (came) {
            EXPECT_EQ(shared_on_a_done.get(), 0) << "A's acceptance of the shared unit is B's reference";
          }
          EXPECT_TRUE(has_passed_acceptance(url, shared));
        }
        const std::string tag = fmt::format("{}-{}", st.name, i++);
        test::Child c = test::start_stand(accept_args(st, unit, seed), st.dir, tag);
        if (unit == killed_unit) {
          EXPECT_TRUE(test::wait_until([&] { return has_recorded_points(url, unit); }, 600,
                                       std::chrono::milliseconds(100)))
              << "the unit to be killed never recorded a point";
          c.signal(SIGKILL);
        }
        const int code = c.wait(600);
        if (st.name == "stand-A" && unit == shared) shared_on_a.set_value(code);
        std::lock_guard<std::mutex> lock(m);
        results[st.name].push_back({code, c.out(), c.err()});
      }
    });
  }
  for (auto& t : threads) t.join();

  // 19 verdicts (pass 0 or fail 3) and one killed process.
  int verdicts = 0, killed = 0;
  std::string shared_on_b;
  for (const auto& st : stands) {
    ASSERT_EQ(results[st.name].size(), 5u);
    for (size_t i = 0; i < 5; ++i) {
      const auto& r = results[st.name][i];
      if (plan[st.name][i].first == killed_unit && st.name == "stand-D") {
        EXPECT_EQ(r.code, 128 + SIGKILL);
        ++killed;
        continue;
      }
      EXPECT_TRUE(r.code == 0 || r.code == 3) << st.name << " " << plan[st.name][i].first << ": " << r.code << "\n"
                                              << r.err;
      if (r.code == 0 || r.code == 3) ++verdicts;
      if (st.name == "stand-B" && plan[st.name][i].first == shared) shared_on_b = r.out;
    }
  }
  EXPECT_EQ(verdicts, 19);
  EXPECT_EQ(killed, 1);

  const auto cat = open_catalogue(url, Catalogue::Mode::read_only);
  const auto runs = cat->list_runs();
  ASSERT_EQ(runs.size(), 20u);
  std::set<std::string> run_ids;
  int stale = 0;
  std::map<std::string, int> per_stand;
  for (const auto& r : runs) {
    EXPECT_TRUE(run_ids.insert(r.run_id).second) << "duplicate run id " << r.run_id;
    EXPECT_EQ(r.run_id.size(), 36u) << r.run_id;  // a UUID
    EXPECT_EQ(r.run_id[14], '7') << r.run_id;     // version 7
    EXPECT_EQ(r.host, this_host());
    EXPECT_TRUE(fs::exists(fs::path(r.run_dir) / "run.json")) << r.run_dir;
    ++per_stand[r.stand];
    if (r.stale()) {
      ++stale;
      EXPECT_EQ(r.unit, killed_unit);
      EXPECT_EQ(r.stand, "stand-D");
    } else {
      EXPECT_FALSE(r.running()) << r.run_id;
    }
  }
  EXPECT_EQ(stale, 1);
  for (const auto& st : stands) EXPECT_EQ(per_stand[st.name], 5) << st.name;

  // Every unit's history is consistent: its calibrations and acceptances name runs of that unit,
  // on the stand that made them; no id twice.
  std::set<int64_t> cal_ids, acc_ids;
  int acceptances = 0;
  for (const auto& u : cat->units()) {
    for (const auto& c : cat->unit_history(u)) {
      EXPECT_TRUE(cal_ids.insert(c.id).second);
      const auto run = cat->find_run(c.run_id.value());
      ASSERT_TRUE(run);
      EXPECT_EQ(run->unit, u);
      EXPECT_EQ(run->stand, c.stand);
    }
    for (const auto& a : cat->unit_acceptances(u)) {
      EXPECT_TRUE(acc_ids.insert(a.id).second);
      ++acceptances;
      const auto run = cat->find_run(a.run_id.value());
      ASSERT_TRUE(run);
      EXPECT_EQ(run->unit, u);
      EXPECT_EQ(a.stand, run->stand);
      EXPECT_EQ(a.certificate["run"]["id"], a.run_id.value());
    }
  }
  EXPECT_EQ(acceptances, 19);

  // The shared unit: calibrated on A and on B; B's acceptance judged consistency against A's.
  const auto h = cat->unit_history(shared);
  ASSERT_EQ(h.size(), 2u);
  EXPECT_EQ(h[0].stand, "stand-A");
  EXPECT_EQ(h[1].stand, "stand-B");
  ASSERT_FALSE(shared_on_b.empty());
  const auto cert = nlohmann::json::parse(shared_on_b);
  bool consistency = false;
  for (const auto& c : cert["criteria"]) {
    if (c["id"] != "consistency") continue;
    consistency = true;
    EXPECT_NE(c.dump().find(h[0].run_id.value()), std::string::npos) << c.dump();  // A's run is the reference
  }
  EXPECT_TRUE(consistency) << shared_on_b;

  // The commands read the same fleet: history across stands, runs with the stale one.
  CommandResult r = test::run_stand({"history", shared, "--catalogue", url, "--json"}, tmp.path(), "history");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["calibrations"].size(), 2u);
  r = test::run_stand({"runs", "--db", url, "--json"}, tmp.path(), "runs");
  ASSERT_EQ(r.code, 0) << r.err;
  int stale_listed = 0;
  for (const auto& j : nlohmann::json::parse(r.out)) stale_listed += j["stale"].get<bool>() ? 1 : 0;
  EXPECT_EQ(stale_listed, 1);
  // Re-indexing a stand's folders into the server finds everything there already.
  r = test::run_stand({"catalogue", "rebuild", "--runs-dir", stands[0].runs.string(), "--catalogue", url, "--json"},
                      tmp.path(), "rebuild");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto rb = nlohmann::json::parse(r.out);
  EXPECT_EQ(rb["folders"], 5);
  EXPECT_EQ(rb["runs_added"].get<int>() + rb["calibrations_added"].get<int>() + rb["acceptances_added"].get<int>(), 0);
}

// The server goes away mid-run and comes back: the run completes on its folder, and its entry
// (run, calibration, acceptance) appears once the database is back.
TEST(Fleet, TheDatabaseAwayMidRunTheEntryCatchesUp) {
  test::PgServer pg;
  const std::string url = pg.create_database("restart");
  test::TempDir tmp;
  const Stand st = make_stand(tmp.path(), "stand-R", url);
  test::Child c = test::start_stand(accept_args(st, "RESTART-1", 5), tmp.path(), "accept");
  ASSERT_TRUE(test::wait_until([&] { return has_recorded_points(url, "RESTART-1"); }, 120, std::chrono::milliseconds(50))) << c.err();
  pg.stop();
  // The calibration could not be recorded: the folder says so, and the run goes on.
  fs::path run_dir;
  ASSERT_TRUE(test::wait_until(
      [&] {
        for (const auto& e : fs::directory_iterator(st.runs)) {
          if (fs::exists(e.path() / "catalogue.pending")) run_dir = e.path();
        }
        return !run_dir.empty();
      },
      120, std::chrono::milliseconds(50)))
      << c.err();
  pg.start();
  const int code = c.wait(240);
  EXPECT_EQ(code, 0) << c.err() << c.out();
  EXPECT_FALSE(fs::exists(run_dir / "catalogue.pending"));
  const auto cat = open_catalogue(url, Catalogue::Mode::read_only);
  const auto runs = cat->list_runs();
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0].outcome, RunOutcome::completed);
  EXPECT_EQ(runs[0].stand, "stand-R");
  EXPECT_EQ(cat->unit_history("RESTART-1").size(), 1u);
  ASSERT_EQ(cat->unit_acceptances("RESTART-1").size(), 1u);
  EXPECT_TRUE(cat->unit_acceptances("RESTART-1")[0].passed);

  // And a plain `pg_ctl restart` in the middle of another run: it completes, its entry is whole.
  test::Child c2 = test::start_stand(accept_args(st, "RESTART-2", 6), tmp.path(), "accept2");
  ASSERT_TRUE(test::wait_until([&] { return has_recorded_points(url, "RESTART-2"); }, 120, std::chrono::milliseconds(50)))
      << c2.err();
  pg.restart();
  EXPECT_EQ(c2.wait(240), 0) << c2.err() << c2.out();
  const auto after = open_catalogue(url, Catalogue::Mode::read_only);
  const auto r2 = after->list_runs({.unit = "RESTART-2", .limit = 0});
  ASSERT_EQ(r2.size(), 1u);
  EXPECT_EQ(r2[0].outcome, RunOutcome::completed);
  EXPECT_EQ(after->unit_history("RESTART-2").size(), 1u);
  EXPECT_EQ(after->unit_acceptances("RESTART-2").size(), 1u);
}

// The database down for a whole run and beyond its wait: the run completes on its folder (exit 1,
// the folder marked), the next run on the folder catches it up, and `catalogue rebuild` does the
// same by hand.
TEST(Fleet, ARunTheDatabaseMissedCatchesUpOnTheNextRunOrARebuild) {
  test::PgServer pg;
  const std::string url = pg.create_database("missed");
  open_catalogue(url);  // the schema
  test::TempDir tmp;
  const fs::path runs = tmp.path() / "runs";
  // A short grid (the shipped one, coarser): enough for a calibration, a few seconds per run.
  const std::string grid = test::write_file(tmp.path() / "short_grid.yaml",
                                            "name: short_grid\nsteps:\n  - home\n  - null_offset_grid:\n"
                                            "      axes: [pitch, yaw]\n      extent_deg: 0.42\n      step_deg: 0.06\n"
                                            "      settle_s: 0.2\n      frames: 5\n  - calibrate:\n"
                                            "      method: differences\n")
                               .string();
  auto run = [&](const std::string& tag) {
    return test::run_stand({"run", grid, "--emulate", "--speed", kSpeed, "--quiet", "--runs-dir", runs.string(),
                            "--catalogue", url, "--catalogue-wait", "1"},
                           tmp.path(), tag, 240);
  };
  pg.stop();
  CommandResult r = run("down1");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("catalogue rebuild"), std::string::npos) << r.err;
  r = run("down2");
  EXPECT_EQ(r.code, 1) << r.err;
  std::vector<fs::path> marked;
  for (const auto& e : fs::directory_iterator(runs)) {
    EXPECT_TRUE(fs::exists(e.path() / "run.json"));
    if (fs::exists(e.path() / "catalogue.pending")) marked.push_back(e.path());
  }
  ASSERT_EQ(marked.size(), 2u);
  pg.start();
  // By hand, one folder's worth: rebuild indexes both and removes both marks.
  r = test::run_stand({"catalogue", "rebuild", "--runs-dir", runs.string(), "--catalogue", url, "--json"}, tmp.path(),
                      "rebuild");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(nlohmann::json::parse(r.out)["runs_added"], 2);
  EXPECT_EQ(nlohmann::json::parse(r.out)["calibrations_added"], 2);
  for (const auto& m : marked) EXPECT_FALSE(fs::exists(m / "catalogue.pending"));
  // Down again for one run; the next run, with the database back, catches the missed one up.
  pg.stop();
  EXPECT_EQ(run("down3").code, 1);
  pg.start();
  r = run("up");
  EXPECT_EQ(r.code, 0) << r.err;
  const auto cat = open_catalogue(url, Catalogue::Mode::read_only);
  const auto all = cat->list_runs();
  EXPECT_EQ(all.size(), 4u);
  for (const auto& x : all) EXPECT_EQ(x.outcome, RunOutcome::completed) << x.run_id;
  for (const auto& e : fs::directory_iterator(runs)) EXPECT_FALSE(fs::exists(e.path() / "catalogue.pending"));
}

}  // namespace
}  // namespace fpss
