// run.json as one type (stand/catalogue/run_file.h): what the session writes reads back to the same
// keys and bytes, keys it does not know are kept, and bad values are InputErrors naming the key.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>

#include "base/errors.h"
#include "stand/catalogue/run_file.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

using ::testing::HasSubstr;
using json = nlohmann::json;

// run.json of an accepted, resumed run with an adaptive stop, as the session and accept write it.
json full_run() {
  return json::parse(R"({
  "acceptance": {"certificate": "certificate.txt", "failed": ["jitter_pitch"], "file": "acceptance.json",
                 "limits": {"file": "procedures/acceptance_limits.yaml", "sha256": "ab12"}, "verdict": "fail"},
  "adaptive_stops": [{"axes": "pitch", "first_skipped_point": 12, "points_skipped": 5,
                      "reason": "adaptive stop: the live fit's largest 1-sigma 0.0290 arcsec is at most the target 0.0300 arcsec",
                      "sigma_max_arcsec": 0.029, "step": 2, "until_sigma_arcsec": 0.03}],
  "emulated": true,
  "emulator": {"effects": [], "seed": 3, "speed": 100.0},
  "ended_utc": "2024-05-01T12:05:00Z",
  "files": {"calibration": "calibration-2.json", "event_stream": "events.jsonl", "events": "events.log",
            "gap": "GAP.json", "journal": "points.jsonl", "samples": "samples.csv"},
  "format": "fpss-stand run/1",
  "operator": "A. Operator",
  "outcome": "completed",
  "points": {"completed": 113, "skipped": 5, "total": 113},
  "procedure": {"file": "procedures/adaptive_grid.yaml", "name": "adaptive_grid", "sha256": "3f2a", "text": "steps: []\n"},
  "reason": "resumed once",
  "run_id": "01a20941-3f48-7c55-9d29-47b0f74c07c6",
  "safe_state": true,
  "sensor_id": "FPSS SN=FPSS1,FW=2.1",
  "sessions": [
    {"ended_utc": "2024-05-01T12:01:00Z", "first_point": 1, "outcome": "interrupted", "pid": 41, "points_completed": 20,
     "reason": "interrupted by a signal", "session": 1, "started_utc": "2024-05-01T12:00:00Z",
     "emulator": {"command": ["fpss-stand", "emulate"], "gimbal": "tcp://127.0.0.1:1502", "sensor": "pty:/dev/pts/3"}},
    {"engine": {"bench_s": 9.5, "wall_s": 10.25}, "ended_utc": "2024-05-01T12:05:00Z", "first_point": 21, "outcome": "completed",
     "pid": 42, "points_completed": 113, "sensor_stats": {"frames": 4000}, "session": 2, "started_utc": "2024-05-01T12:02:00Z"}],
  "signed_off_utc": "2024-05-01T12:00:05Z",
  "software": {"name": "fpss-stand", "version": "0.9.0"},
  "stand": {"file": null, "settings": {"stand": ""}, "text": null},
  "started_utc": "2024-05-01T12:00:00Z",
  "stop_cause": "none",
  "unit": "FPSS1"
})");
}

TEST(RunFile, WhatIsWrittenReadsBackToTheSameKeysAndBytes) {
  const json j = full_run();
  const RunFile r = run_file_from_json(j, "run.json");
  EXPECT_EQ(to_json(r), j);
  EXPECT_EQ(to_json(r).dump(2), j.dump(2));
  // The typed values.
  EXPECT_EQ(r.id_or("x"), "01a20941-3f48-7c55-9d29-47b0f74c07c6");
  EXPECT_EQ(r.stop_cause, StopCause::none);
  EXPECT_EQ(r.points.skipped, 5);
  ASSERT_EQ(r.sessions.size(), 2u);
  EXPECT_EQ(r.sessions[1].first_point, 21);
  EXPECT_FALSE(r.sessions[0].engine);
  ASSERT_TRUE(r.acceptance);
  EXPECT_EQ(r.acceptance->verdict, "fail");
  ASSERT_TRUE(r.stand);
  EXPECT_FALSE(r.stand->file);
  EXPECT_EQ(r.files.calibration, "calibration-2.json");
  ASSERT_TRUE(r.adaptive_stops);
  EXPECT_EQ((*r.adaptive_stops)[0].first_skipped_point, 12);
}

TEST(RunFile, OptionalKeysStayAbsentAndUnknownKeysAreKept) {
  json j = full_run();
  for (const char* k : {"acceptance", "adaptive_stops", "ended_utc", "operator", "reason", "run_id", "safe_state",
                        "signed_off_utc", "stop_cause", "emulator", "sensor_id", "software", "stand", "format"}) {
    j.erase(k);
  }
  j["points"].erase("skipped");
  j["files"] = {{"samples", "samples.csv"}};
  j["sessions"] = json::array({{{"session", 1}, {"pid", 7}}});
  j["from_a_later_version"] = {{"x", 1}};
  const RunFile r = run_file_from_json(j, "run.json");
  EXPECT_FALSE(r.run_id);
  EXPECT_EQ(r.id_or("/runs/20240501T120000Z-FPSS1-g"), "20240501T120000Z-FPSS1-g");
  EXPECT_FALSE(r.stop_cause);
  EXPECT_EQ(to_json(r), j);
  // An adaptive stop whose sigma was not known.
  j = full_run();
  j["adaptive_stops"][0]["sigma_max_arcsec"] = nullptr;
  j["adaptive_stops"][0]["first_skipped_point"] = nullptr;
  EXPECT_EQ(to_json(run_file_from_json(j, "run.json")), j);
}

std::string error_with(const std::function<void(json&)>& change) {
  json j = full_run();
  change(j);
  try {
    run_file_from_json(j, "/runs/r/run.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(RunFile, BadValuesNameTheFileAndTheKey) {
  auto expect = [](const std::string& m, const std::string& key) {
    EXPECT_THAT(m, HasSubstr("/runs/r/run.json"));
    EXPECT_THAT(m, HasSubstr("key \"" + key + "\"")) << m;
  };
  expect(error_with([](json& j) { j["points"]["total"] = "many"; }), "points.total");
  expect(error_with([](json& j) { j.erase("unit"); }), "unit");
  expect(error_with([](json& j) { j["outcome"] = "done"; }), "outcome");
  expect(error_with([](json& j) { j["stop_cause"] = "gremlins"; }), "stop_cause");
  expect(error_with([](json& j) { j["emulated"] = "yes"; }), "emulated");
  expect(error_with([](json& j) { j["sessions"][1]["pid"] = "42"; }), "sessions[1].pid");
  expect(error_with([](json& j) { j["procedure"].erase("sha256"); }), "procedure.sha256");
  expect(error_with([](json& j) { j["files"]["calibration"] = 2; }), "files.calibration");
  expect(error_with([](json& j) { j["acceptance"]["verdict"] = "maybe"; }), "acceptance.verdict");
  expect(error_with([](json& j) { j["adaptive_stops"][0]["step"] = 2.5; }), "adaptive_stops[0].step");
  EXPECT_THROW(run_file_from_json(json::array(), "run.json"), InputError);
}

TEST(RunFile, ReadAndWrittenInAFolder) {
  test::TempDir tmp("run-file");
  const RunFile r = run_file_from_json(full_run(), "run.json");
  write_run_file(tmp.path(), r);
  EXPECT_EQ(test::read_file(tmp / "run.json"), full_run().dump(2) + "\n");
  EXPECT_EQ(to_json(read_run_file(tmp.path())), full_run());
  test::write_file(tmp / "run.json", R"({"unit": "U", "unit": "V"})");
  EXPECT_THAT(test::error_of<InputError>([&] { read_run_file(tmp.path()); }), HasSubstr("unit"));
}

}  // namespace
}  // namespace fpss
