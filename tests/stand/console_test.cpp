// `fpss-stand serve` over real HTTP on loopback: the token guards control (401), bounded requests,
// no CORS, the live-client cap; a run outlives its console (serve killed mid-run) and a restarted
// console shows it live, lets its stream catch up and keeps the queue; a job's run is found by its
// child's pid and start, never an earlier run of a reused pid. ~25 s (two emulated grid runs at --speed 20).
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <regex>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "base/unique_fd.h"
#include "stand/catalogue/sqlite_catalogue.h"
#include "stand/console/run_files.h"
#include "tests/stand/catalogue_fixtures.h"
#include "tests/stand/emulator_stand.h"
#include "tests/support/test_support.h"

namespace {

using namespace fpss::test;
using json = nlohmann::json;

struct Serve {
  std::unique_ptr<Child> child;
  int port = 0;
  std::string banner;
  // `extra` without --stand: the emulated bench.
  Serve(const TempDir& t, const std::vector<std::string>& extra, const std::string& tag) {
    std::vector<std::string> args{"serve", "--runs-dir", (t / "runs").string()};
    if (std::find(extra.begin(), extra.end(), "--stand") == extra.end()) args.push_back("--emulate");
    args.insert(args.end(), extra.begin(), extra.end());
    child = std::make_unique<Child>(stand_argv(args), fs::path(), t / (tag + ".err"));
    const auto first = child->line(30);
    EXPECT_TRUE(first) << read_file(t / (tag + ".err"));
    banner = first.value_or("");
    for (int i = 0; i < 2; ++i) {
      if (auto l = child->line(2)) banner += "\n" + *l;
    }
    std::smatch m;
    if (std::regex_search(banner, m, std::regex(R"(:(\d+)/)"))) port = std::stoi(m[1]);
  }
  httplib::Client client() const {
    httplib::Client c("127.0.0.1", port);
    c.set_read_timeout(10, 0);
    return c;
  }
};

std::string token_of(const TempDir& t) {
  std::string s = read_file(t / "runs" / "console.token");
  while (!s.empty() && s.back() == '\n') s.pop_back();
  return s;
}

// The run id job `id` started, once its run is in the catalogue ("" after a minute without).
std::string run_of_job(httplib::Client& c, int id) {
  std::string run_id;
  EXPECT_TRUE(wait_until([&] {
    auto j = json::parse(c.Get(("/api/jobs/" + std::to_string(id)).c_str())->body);
    if (j["run_id"].is_string()) run_id = j["run_id"];
    return !run_id.empty();
  }, 60)) << "job " << id << " never named its run";
  return run_id;
}

TEST(Console, ControlNeedsTheTokenAndRequestsAreBounded) {
  TempDir t;
  Serve s(t, {"--listen", "127.0.0.1:0", "--max-clients", "1"}, "serve1");
  ASSERT_GT(s.port, 0) << s.banner;
  const std::string tok = token_of(t);
  ASSERT_EQ(tok.size(), 64u);
  EXPECT_NE(s.banner.find(tok), std::string::npos) << "the token is printed on first start";
  struct stat st {};
  ASSERT_EQ(::stat((t / "runs" / "console.token").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);

  auto c = s.client();
  const std::string job = R"({"procedure":"discrete_grid.yaml","unit":"FPSS-S1"})";
  auto r = c.Post("/api/jobs", job, "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 401);
  r = c.Post("/api/jobs", {{"Authorization", "Bearer " + std::string(64, '0')}}, job, "application/json");
  EXPECT_EQ(r->status, 401);
  r = c.Post("/api/runs/any/control", R"({"action":"abort"})", "application/json");
  EXPECT_EQ(r->status, 401);
  r = c.Delete("/api/jobs/1");
  EXPECT_EQ(r->status, 401);
  // Reads on loopback need no token; no wildcard (or any) CORS header.
  r = c.Get("/api/status", {{"Origin", "http://evil.example"}});
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_FALSE(r->has_header("Access-Control-Allow-Origin"));
  // A rebound DNS name on loopback is refused.
  r = c.Get("/api/status", {{"Host", "evil.example:80"}});
  EXPECT_EQ(r->status, 403);
  // Bounded bodies and headers.
  const httplib::Headers auth{{"Authorization", "Bearer " + tok}};
  r = c.Post("/api/jobs", auth, std::string(200 * 1024, ' '), "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 413);
  r = c.Get("/api/status", {{"X-Big", std::string(20000, 'x')}});
  EXPECT_TRUE(!r || r->status >= 400);
  // Bad input is 400 with a reason; a procedure outside the folder is refused.
  r = c.Post("/api/jobs", auth, R"({"procedure":"../../etc/passwd"})", "application/json");
  EXPECT_EQ(r->status, 400);
  r = c.Post("/api/jobs", auth, "not json", "application/json");
  EXPECT_EQ(r->status, 400);
  r = c.Post("/api/jobs", auth, std::string(30000, '[') + std::string(30000, ']'), "application/json");
  EXPECT_EQ(r->status, 400) << "nesting is bounded";
  r = c.Post("/api/jobs", auth, R"({"unit":"A","unit":"B"})", "application/json");
  EXPECT_EQ(r->status, 400) << "a key given twice";
  // A file outside a run folder is never served.
  r = c.Get("/runs/x/..%2f..%2fconsole.token");
  EXPECT_EQ(r->status, 404);

  // A plan's jobs at once (POST /api/jobs/batch): one bad job refuses them all, naming it.
  r = c.Post("/api/jobs/batch", auth, R"({"jobs":[)" + job + R"(,{"procedure":"nope.yaml","unit":"X"}]})", "application/json");
  ASSERT_EQ(r->status, 400) << r->body;
  EXPECT_NE(r->body.find("jobs[1]: procedure"), std::string::npos) << r->body;
  EXPECT_EQ(json::parse(c.Get("/api/jobs")->body).size(), 0u) << "nothing was queued";
  EXPECT_EQ(c.Post("/api/jobs/batch", R"({"jobs":[]})", "application/json")->status, 401);
  // The live-client cap (1 here): a second event stream is refused while the first is open.
  r = c.Post("/api/jobs/batch", auth, R"({"stand":"S1","jobs":[)" + job + R"(,{"procedure":"discrete_grid.yaml","unit":"FPSS-S2"}]})",
             "application/json");
  ASSERT_EQ(r->status, 201) << r->body;
  const json queued = json::parse(r->body)["jobs"];
  ASSERT_EQ(queued.size(), 2u);
  EXPECT_EQ(queued[0]["id"], 1);
  EXPECT_EQ(queued[1]["unit"], "FPSS-S2");
  // The second waits for the first: remove it so the test ends with the first run.
  EXPECT_EQ(c.Delete("/api/jobs/2", auth)->status, 200);
  const std::string run_id = run_of_job(c, 1);
  ASSERT_FALSE(run_id.empty());
  std::atomic<bool> got{false};
  std::thread first([&] {
    httplib::Client c1("127.0.0.1", s.port);
    c1.Get(("/api/runs/" + run_id + "/stream").c_str(), [&](const char*, size_t) {
      got = true;
      return false;  // one chunk is enough
    });
  });
  ASSERT_TRUE(wait_until([&] { return got.load(); }, 30));
  first.join();
  // The first stream is closed by now; hold one open and ask for another.
  std::atomic<bool> hold{true}, holding{false};
  std::thread holder([&] {
    httplib::Client c2("127.0.0.1", s.port);
    c2.Get(("/api/runs/" + run_id + "/stream").c_str(), [&](const char*, size_t) {
      holding = true;
      return hold.load();
    });
  });
  ASSERT_TRUE(wait_until([&] { return holding.load(); }, 30));
  r = c.Get(("/api/runs/" + run_id + "/events?from=0").c_str());
  EXPECT_EQ(r->status, 200);
  int status = 0;
  s.client().Get(("/api/runs/" + run_id + "/stream").c_str(), [&](const httplib::Response& x) {
    status = x.status;
    return false;
  }, [](const char*, size_t) { return false; });
  EXPECT_EQ(status, 503);
  hold = false;
  holder.join();
  // Abort the run (with the token) so the test ends soon.
  r = c.Post(("/api/runs/" + run_id + "/control").c_str(), auth, R"({"action":"abort"})", "application/json");
  EXPECT_EQ(r->status, 200) << r->body;
  EXPECT_TRUE(wait_until([&] {
    auto j = c.Get(("/api/runs/" + run_id).c_str());
    return j && json::parse(j->body).value("stop_cause", "") == "aborted";
  }, 60));
  s.child->signal(SIGTERM);
  EXPECT_EQ(s.child->wait(20), 0);

  // A second start does not print the token again; off loopback reads need it too.
  Serve again(t, {"--listen", "0.0.0.0:0"}, "serve2");
  ASSERT_GT(again.port, 0) << again.banner;
  EXPECT_EQ(again.banner.find(tok), std::string::npos);
  auto c3 = again.client();
  r = c3.Get("/api/status");
  EXPECT_EQ(r->status, 401);
  r = c3.Get("/api/status", auth);
  EXPECT_EQ(r->status, 200);
  r = c3.Get("/index.html");
  EXPECT_EQ(r->status, 200) << "the page itself (no data) loads, so the token can be given";
}

TEST(Console, AnInvestigationIsQueuedAsAJobAndWritesItsRecord) {
  TempDir t;
  Serve s(t, {"--listen", "127.0.0.1:0", "--speed", "20", "--effect", "time_skew:skew_s=0.004"}, "serve-inv");
  ASSERT_GT(s.port, 0) << s.banner;
  const httplib::Headers auth{{"Authorization", "Bearer " + token_of(t)}};
  auto c = s.client();
  // The model is a published set's name, nothing else.
  auto r = c.Post("/api/jobs", auth, R"({"kind":"investigate","model":"../../etc/passwd"})", "application/json");
  ASSERT_EQ(r->status, 400);
  EXPECT_NE(r->body.find("model"), std::string::npos) << r->body;
  r = c.Post("/api/jobs", auth, R"({"kind":"run","procedure":"discrete_grid.yaml","model":"a-6-fpss1"})",
             "application/json");
  EXPECT_EQ(r->status, 400) << "only an investigation takes a model";
  r = c.Post("/api/jobs", auth,
             R"({"kind":"investigate","model":"a-6-fpss1","procedure":"discrete_grid.yaml","unit":"FPSS-I1"})",
             "application/json");
  ASSERT_EQ(r->status, 201) << r->body;
  const int64_t id = json::parse(r->body)["id"];
  json job;
  ASSERT_TRUE(wait_until([&] {
    job = json::parse(c.Get(("/api/jobs/" + std::to_string(id)).c_str())->body);
    return job["state"] == "finished";
  }, 240)) << job.dump();
  EXPECT_EQ(job["exit_code"], 0) << read_file(t / "runs" / ".console" / ("job-" + std::to_string(id) + ".log"));
  EXPECT_EQ(job["kind"], "investigate");
  // The job names its investigation's folder, in the runs folder.
  ASSERT_TRUE(job["investigation"].is_string()) << job.dump();
  const std::string name = job["investigation"];
  EXPECT_EQ(name.rfind("investigation-", 0), 0u) << name;
  const fs::path record = t / "runs" / name / "INVESTIGATION.json";
  ASSERT_TRUE(fs::exists(record));
  const json inv = json::parse(read_file(record));
  EXPECT_EQ(inv["cause"], "time_skew") << inv.dump(1);
  EXPECT_GE(inv["runs"].size(), 2u);

  // The console lists it with what it found and serves its report; nothing outside its folder.
  const json list = json::parse(c.Get("/api/investigations")->body);
  ASSERT_EQ(list.size(), 1u) << list.dump(1);
  EXPECT_EQ(list[0]["name"], name);
  EXPECT_EQ(list[0]["cause"], "time_skew");
  EXPECT_EQ(list[0]["causes"][0]["name"], "time_skew");
  EXPECT_EQ(list[0]["runs"].size(), inv["runs"].size());
  EXPECT_EQ(list[0]["runs"][0], fs::path(inv["runs"][0].get<std::string>()).filename().string());
  const std::string page = list[0]["files"]["INVESTIGATION.html"];
  auto got = c.Get(page.c_str());
  ASSERT_EQ(got->status, 200) << page;
  EXPECT_EQ(got->get_header_value("Content-Type"), "text/html; charset=utf-8");
  EXPECT_NE(got->body.find("time_skew"), std::string::npos);
  fs::create_directory_symlink(t / "runs" / name, t / "runs" / "investigation-link");
  for (const std::string& bad : std::vector<std::string>{"/investigations/investigation-link/INVESTIGATION.json",
                                                         "/investigations/runs/INVESTIGATION.json",
                                "/investigations/" + name + "/../stand.db", "/investigations/" + name + "/.hidden"}) {
    EXPECT_EQ(c.Get(bad.c_str())->status, 404) << bad;
  }
  EXPECT_EQ(json::parse(c.Get("/api/investigations")->body).size(), 1u) << "a link is not an investigation";
  // Records that are not one: unreadable JSON, and one over 2 MiB, are left out of the list.
  fs::create_directory(t / "runs" / "investigation-broken");
  write_file(t / "runs" / "investigation-broken" / "INVESTIGATION.json", "{\"cause\": ");
  fs::create_directory(t / "runs" / "investigation-huge");
  write_file(t / "runs" / "investigation-huge" / "INVESTIGATION.json",
             "{\"cause\": \"" + std::string(3u << 20, 'x') + "\"}");
  const json after = json::parse(c.Get("/api/investigations")->body);
  ASSERT_EQ(after.size(), 1u) << after.dump().substr(0, 300);
  EXPECT_EQ(after[0]["name"], name);
}

TEST(Console, ARunOutlivesItsConsoleAndARestartedConsoleShowsItLive) {
  TempDir t;
  Serve s(t, {"--listen", "127.0.0.1:0"}, "serve1");
  ASSERT_GT(s.port, 0);
  const httplib::Headers auth{{"Authorization", "Bearer " + token_of(t)}};
  auto c = s.client();
  auto r = c.Post("/api/jobs", auth, R"({"procedure":"discrete_grid.yaml","unit":"FPSS-K1"})", "application/json");
  ASSERT_EQ(r->status, 201);
  const std::string run_id = run_of_job(c, 1);
  ASSERT_FALSE(run_id.empty());
  fs::path dir;
  ASSERT_TRUE(wait_until([&] {
    dir = run_folder_of(t / "runs", run_id);
    return fs::exists(dir / "run.json");
  }, 60));
  ASSERT_TRUE(wait_until([&] { return read_file(dir / "events.jsonl").find("\"point\":5,") != std::string::npos; }, 60));
  // A second job waits in the queue; it is kept across the console's restart.
  r = c.Post("/api/jobs", auth, R"({"procedure":"discrete_grid.yaml","unit":"FPSS-K2"})", "application/json");
  ASSERT_EQ(r->status, 201);
  s.child->signal(SIGKILL);
  s.child->wait(10);

  // A restarted console shows the run live, and its stream catches up from any offset.
  Serve again(t, {"--listen", "127.0.0.1:0"}, "serve2");
  ASSERT_GT(again.port, 0);
  auto c2 = again.client();
  auto st = json::parse(c2.Get("/api/status")->body);
  ASSERT_EQ(st["live_runs"].size(), 1u) << st.dump();
  EXPECT_EQ(st["live_runs"][0], run_id);
  const json jobs = json::parse(c2.Get("/api/jobs")->body);
  ASSERT_EQ(jobs.size(), 1u) << jobs.dump();
  EXPECT_EQ(jobs[0]["unit"], "FPSS-K2");
  EXPECT_EQ(jobs[0]["state"], "queued");
  EXPECT_EQ(c2.Delete(("/api/jobs/" + std::to_string(jobs[0]["id"].get<int64_t>())).c_str(), auth)->status, 200);
  std::string stream;
  httplib::Client cs("127.0.0.1", again.port);
  cs.Get(("/api/runs/" + run_id + "/stream").c_str(), {{"Last-Event-ID", "0"}}, [&](const char* d, size_t n) {
    stream.append(d, n);
    return stream.find("\"run_stopped\"") == std::string::npos;
  });
  EXPECT_NE(stream.find("\"run_started\""), std::string::npos);
  EXPECT_NE(stream.find("\"run_stopped\""), std::string::npos);
  // Resuming from an id continues after it: the first event is not sent again.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(stream, m, std::regex(R"(id: (\d+))")));
  std::string tail;
  cs.Get(("/api/runs/" + run_id + "/stream").c_str(), {{"Last-Event-ID", m[1].str()}}, [&](const char* d, size_t n) {
    tail.append(d, n);
    return false;
  });
  EXPECT_EQ(tail.find("\"run_started\""), std::string::npos);

  // The run completed although its console was killed.
  ASSERT_TRUE(wait_until([&] { return json::parse(read_file(dir / "run.json")).value("outcome", "") != "running"; }, 120));
  const json doc = json::parse(read_file(dir / "run.json"));
  EXPECT_EQ(doc["outcome"], "completed");
  EXPECT_EQ(doc["points"]["completed"], doc["points"]["total"]);
  EXPECT_TRUE(wait_until([&] { return fs::exists(dir / "report.html"); }, 60));
  json run;
  EXPECT_TRUE(wait_until([&] {
    run = json::parse(c2.Get(("/api/runs/" + run_id).c_str())->body);
    return !run["live"].get<bool>();
  }, 60));
  EXPECT_EQ(run["outcome"], "completed");
  EXPECT_TRUE(run["files"].contains("report.html"));
  again.child->signal(SIGTERM);
  EXPECT_EQ(again.child->wait(20), 0);
}

// A console of a real stand (`--stand`, here a running `fpss-stand emulate` behind the shipped
// emulator_stand.yaml): its runs use the stand file, not an emulator of their own. A second
// console on the same runs folder is refused (one queue, one stand).
TEST(Console, ServeStandRunsOnTheStandAndOneConsolePerRunsFolder) {
  TempDir t;
  EmulatorStand es(t);
  ASSERT_FALSE(es.stand_file.empty());
  fs::create_directories(t / "procs");
  write_file(t / "procs" / "small.yaml",
             "name: small\nsteps:\n  - home\n"
             "  - null_offset_grid: {extent_deg: 0.4, step_deg: 0.1, frames: 5, settle_s: 0.2}\n"
             "  - calibrate: {method: differences}\n");
  Serve s(t, {"--stand", es.stand_file.string(), "--procedures", (t / "procs").string(), "--listen", "127.0.0.1:0"},
          "serve1");
  ASSERT_GT(s.port, 0) << s.banner;

  Child second(stand_argv({"serve", "--emulate", "--runs-dir", (t / "runs").string(), "--listen", "127.0.0.1:0"}),
               fs::path(), t / "second.err");
  EXPECT_EQ(second.wait(30), 2);
  EXPECT_NE(read_file(t / "second.err").find("console is in use by another fpss-stand"), std::string::npos)
      << read_file(t / "second.err");

  auto c = s.client();
  const json stand = json::parse(c.Get("/api/stand")->body);
  EXPECT_EQ(stand["mode"], "stand");
  EXPECT_EQ(stand["stand_file"], fs::absolute(es.stand_file).string());
  const httplib::Headers auth{{"Authorization", "Bearer " + token_of(t)}};
  auto r = c.Post("/api/jobs", auth, R"({"procedure":"small.yaml","unit":"EMU-0001"})", "application/json");
  ASSERT_EQ(r->status, 201) << r->body;
  const std::string run_id = run_of_job(c, 1);
  ASSERT_FALSE(run_id.empty()) << read_file(t / "serve1.err");
  const fs::path dir = run_folder_of(t / "runs", run_id);
  ASSERT_TRUE(wait_until([&] {
    return fs::exists(dir / "run.json") && json::parse(read_file(dir / "run.json")).value("outcome", "") != "running";
  }, 120));
  const json doc = json::parse(read_file(dir / "run.json"));
  EXPECT_EQ(doc["outcome"], "completed") << doc.dump(1);
  EXPECT_EQ(doc["emulated"], false);
  EXPECT_EQ(doc["points"]["completed"], doc["points"]["total"]);
  EXPECT_TRUE(fs::exists(dir / "calibration.json"));
  s.child->signal(SIGTERM);
  EXPECT_EQ(s.child->wait(20), 0);
  es.emu.signal(SIGTERM);
  EXPECT_EQ(es.emu.wait(30), 0);
}

// A job finds its run by its child's pid; pids are reused (32768 of them on many machines, wrapped
// soon on a busy one), so an earlier run recorded by a process with the same pid is not the job's:
// only a run started in the spawn's second or later is.
TEST(Console, AJobsRunIsNotAnEarlierRunOfAProcessWithTheSamePid) {
  using namespace fpss;
  using console::run_of_pid;
  TempDir tmp("console-pid-reuse");
  const std::filesystem::path runs = tmp / "runs";
  std::filesystem::create_directories(runs);
  SqliteCatalogue cat(Catalogue::default_path(runs));
  cat.record_run_start(make_run("earlier", "FPSS-1", "2026-01-01T00:00:00Z"));
  cat.record_run_end("earlier", RunOutcome::completed, "2026-01-01T00:05:00Z");
  const int pid = static_cast<int>(::getpid());  // both runs are recorded by this process
  console::CataloguePool pool(runs, "");
  EXPECT_FALSE(run_of_pid(pool, pid, "2026-06-01T00:00:00Z"));
  ASSERT_TRUE(run_of_pid(pool, pid, "2025-12-31T23:59:59Z"));  // spawned before it: that run
  cat.record_run_start(make_run("this-job", "FPSS-1", "2026-06-01T00:00:00Z"));
  const auto r = run_of_pid(pool, pid, "2026-06-01T00:00:00Z");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->run_id, "this-job");
}

// A run is live while a process holds its folder's lock, not while some process has its pid: a
// killed run whose pid another process now has is not shown live (nor does it hold the queue).
TEST(Console, ARunIsLiveWhileItsProcessHoldsItsFolderNotItsPid) {
  using namespace fpss;
  TempDir tmp("console-live-lock");
  const std::filesystem::path runs = tmp / "runs", dir = runs / "killed";
  std::filesystem::create_directories(dir);
  write_file(dir / ".lock", "");
  SqliteCatalogue cat(Catalogue::default_path(runs));
  RunStart rs = make_run("killed", "FPSS-1", "2026-06-01T00:00:00Z");
  rs.run_dir = dir;
  cat.record_run_start(rs);  // `running`, with this (live) process's pid
  console::CataloguePool pool(runs, "");
  EXPECT_TRUE(console::live_runs(pool).empty());
  EXPECT_FALSE(console::find_run(pool, "killed")->live);
  const UniqueFd fd(::open((dir / ".lock").c_str(), O_RDWR | O_CLOEXEC));
  ASSERT_TRUE(fd);
  ASSERT_EQ(::flock(fd.get(), LOCK_EX | LOCK_NB), 0);
  EXPECT_EQ(console::live_runs(pool).size(), 1u);
  EXPECT_TRUE(console::find_run(pool, "killed")->live);
}

// The console holds its catalogue for its life: one connection serves request after request and
// sees what the runs write meanwhile; none is made while there is no catalogue, and one whose use
// threw is closed and replaced by a new one.
TEST(Console, TheCatalogueIsOpenedOnceAndReplacedOnlyWhenItsUseFailed) {
  using namespace fpss;
  TempDir tmp("console-pool");
  const std::filesystem::path runs = tmp / "runs";
  std::filesystem::create_directories(runs);
  console::CataloguePool pool(runs, "", 2);
  EXPECT_FALSE(pool.acquire());  // no stand.db yet: no runs, no connection
  EXPECT_EQ(pool.opened(), 0u);
  SqliteCatalogue cat(Catalogue::default_path(runs));
  for (int i = 0; i < 20; ++i) {
    cat.record_run_start(make_run(fmt::format("run-{}", i), "FPSS-1", "2026-06-01T00:00:00Z"));
    auto lease = pool.acquire();
    ASSERT_TRUE(lease);
    EXPECT_EQ(lease->list_runs({.limit = 0}).size(), static_cast<size_t>(i + 1));  // sees the new run
  }
  EXPECT_EQ(pool.opened(), 1u);
  {
    auto a = pool.acquire(), b = pool.acquire();  // two requests at once: two connections
    ASSERT_TRUE(a && b);
    EXPECT_NE(&*a, &*b);
  }
  EXPECT_EQ(pool.opened(), 2u);
  try {
    auto lease = pool.acquire();
    throw std::runtime_error("the connection broke");
  } catch (const std::runtime_error&) {
  }
  (void)pool.acquire();
  (void)pool.acquire();
  EXPECT_EQ(pool.opened(), 2u);  // the two connections held: one broken and closed, one reused
  auto a = pool.acquire(), b = pool.acquire();
  EXPECT_EQ(pool.opened(), 3u);  // the broken one's place took a new connection
}


// A run of two units: the runs list's verdict from its units, the run page's units with their files.
TEST(Console, ARunOfSeveralUnitsShowsEachUnit) {
  TempDir t;
  const auto r = run_stand({"accept", "--emulate", "--bench", (source_dir() / "procedures" / "two_unit_bench.yaml").string(),
                            "--speed", "50", "--runs-dir", (t / "runs").string(), "--quiet", "--no-progress"},
                           t.path(), "accept", 300);
  ASSERT_EQ(r.code, 0) << r.err;
  Serve s(t, {"--listen", "127.0.0.1:0"}, "serve");
  ASSERT_GT(s.port, 0);
  auto c = s.client();
  const json runs = json::parse(c.Get("/api/runs")->body);
  ASSERT_EQ(runs.size(), 1u) << runs.dump();
  EXPECT_EQ(runs[0]["verdict"], "pass");
  const json run = json::parse(c.Get(("/api/runs/" + runs[0]["run_id"].get<std::string>()).c_str())->body);
  ASSERT_EQ(run["units"].size(), 2u) << run.dump();
  EXPECT_EQ(run["units"][1]["serial"], "FPSS2-A6");
  EXPECT_EQ(run["units"][1]["verdict"], "pass");
  const std::string cert = run["units"][1]["files"]["certificate.txt"];
  const auto got = c.Get(cert.c_str());
  ASSERT_TRUE(got);
  EXPECT_EQ(got->status, 200);
  EXPECT_NE(got->body.find("FPSS2-A6"), std::string::npos);
}

}  // namespace
