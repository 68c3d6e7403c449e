// The event stream read back: every event type round-trips through its events.jsonl line, the
// session's notes are told apart, bad lines are InputErrors naming the file, line and key, and a
// run replayed from its events.jsonl publishes the same events the engine published live.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include "base/errors.h"
#include "base/json_file.h"
#include "procedures/events.h"
#include "tests/procedures/engine_fixture.h"

namespace fpss {
namespace {

using ::testing::HasSubstr;
using test::Bench;
using test::TempDir;
namespace fs = std::filesystem;

const double kNaN = std::numeric_limits<double>::quiet_NaN();

EventPoint a_point(int64_t index, Action::Kind kind = Action::Kind::dwell, Phase phase = Phase::offset) {
  return {index, 2, kind, phase, 720.5, -0.125};
}

// One of every event type, with the values a line can hold (NaN where a line writes null).
std::vector<Event> every_event() {
  auto rows = std::make_shared<const std::vector<RecordedRow>>(3);
  PointDone done{a_point(4), rows, {3, 720.25, -0.5, 101.5, -7.25, 0.5, 0.75}, 2, 1, 21.5, true, "2024-05-01T12:00:01.250Z"};
  PointDone no_temp = done;
  no_temp.temperature_c = kNaN;
  no_temp.rows = nullptr;
  return {
      RunStarted{2, 4, 6, 12.5, {{0, 0, 0}, {1, 720.5, 0}, {5, 0, -360.25}}, "2024-05-01T12:00:00.000Z"},
      PointStarted{a_point(4, Action::Kind::slew, Phase::slew), 3, "2024-05-01T12:00:00.500Z"},
      Samples{a_point(4), nullptr, 17, 2, 3, "2024-05-01T12:00:01.000Z"},
      done,
      no_temp,
      FitUpdated{12, 5, 0.25, kNaN, 0.0625, kNaN, "2024-05-01T12:00:02.000Z"},
      StepStopped{3, "pitch", 0.0412, 0.05, {7, 9, 11}, 2, "2024-05-01T12:00:03.000Z"},
      StepStopped{3, "both", kNaN, 0.05, {}, 1, "2024-05-01T12:00:03.500Z"},
      Paused{5, "2024-05-01T12:00:04.000Z"},
      Resumed{5, "2024-05-01T12:00:05.000Z"},
      Fault{Fault::Level::warning, 6, "point 7: re-measured", "2024-05-01T12:00:06.000Z"},
      Fault{Fault::Level::fault, -1, "the sensor stopped answering", "2024-05-01T12:00:07.000Z"},
      RunStopped{RunOutcome::failed, StopCause::sensor_timeout, "no frames for 2 s", 6, false, "2024-05-01T12:00:08.000Z"},
  };
}

std::string line_of(const Event& e) { return to_json(e).dump(); }

Event back(const std::string& line) { return event_from_json(parse_json_text(line, "events.jsonl:1"), "events.jsonl:1"); }

TEST(Events, EveryEventTypeRoundTripsThroughItsLine) {
  const auto events = every_event();
  std::set<size_t> types;
  for (const Event& e : events) {
    types.insert(e.index());
    const std::string line = line_of(e);
    const Event got = back(line);
    ASSERT_EQ(got.index(), e.index()) << line;
    EXPECT_EQ(line_of(got), line);  // the same line, key for key, byte for byte
  }
  EXPECT_EQ(types.size(), std::variant_size_v<Event>);  // every type is covered

  // The typed values come back, not only the text.
  const auto* d = std::get_if<PointDone>(&events[3]);
  const auto got = std::get<PointDone>(back(line_of(events[3])));
  EXPECT_EQ(got.point, d->point);
  EXPECT_EQ(got.stats, d->stats);
  EXPECT_EQ(got.attempts, 2);
  EXPECT_EQ(got.invalid_frames, 1);
  EXPECT_DOUBLE_EQ(got.temperature_c, 21.5);
  EXPECT_EQ(got.utc, "2024-05-01T12:00:01.250Z");
  EXPECT_FALSE(got.rows);  // the rows are in samples.csv
  EXPECT_TRUE(std::isnan(std::get<PointDone>(back(line_of(events[4]))).temperature_c));
  const auto rs = std::get<RunStarted>(back(line_of(events[0])));
  EXPECT_EQ(rs.first_point, 4);
  EXPECT_EQ(rs.points, std::get<RunStarted>(events[0]).points);
  const auto st = std::get<StepStopped>(back(line_of(events[6])));
  EXPECT_EQ(st.skipped, (std::vector<int64_t>{7, 9, 11}));
  EXPECT_EQ(st.session, 2);
  const auto sm = std::get<Samples>(back(line_of(events[2])));
  EXPECT_EQ(sm.row_count, 17u);
  EXPECT_EQ(sm.session, 3);
  const auto stop = std::get<RunStopped>(back(line_of(events.back())));
  EXPECT_EQ(stop.outcome, RunOutcome::failed);
  EXPECT_EQ(stop.cause, StopCause::sensor_timeout);
  EXPECT_FALSE(stop.safe_state);
  EXPECT_EQ(std::get<Fault>(back(line_of(events[11]))).point, -1);
}

TEST(Events, NotesOfTheSessionAreNotEngineEvents) {
  const std::string prompt = R"({"type":"prompt","utc":"2024-05-01T12:00:00.000Z","id":"operator","text":"Who?","kind":"text"})";
  const EventLine l = event_line_from_json(parse_json_text(prompt, "x"), "x");
  const auto* n = std::get_if<Note>(&l);
  ASSERT_TRUE(n);
  EXPECT_EQ(n->type, "prompt");
  EXPECT_EQ(n->body["id"], "operator");
  EXPECT_FALSE(n->body.contains("type"));
  try {
    event_from_json(parse_json_text(prompt, "x"), "f.jsonl:3");
    ADD_FAILURE() << "a note read as an engine event";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("f.jsonl:3"));
    EXPECT_THAT(e.what(), HasSubstr("\"type\""));
  }
  for (const auto& t : note_types()) {
    const std::string line = R"({"type":")" + t + R"(","utc":"u"})";
    EXPECT_TRUE(std::holds_alternative<Note>(event_line_from_json(parse_json_text(line, "x"), "x"))) << t;
  }
}

std::string error_of(const std::string& line) {
  try {
    back(line);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(Events, BadLinesNameTheKey) {
  const std::string done = line_of(every_event()[3]);
  auto with = [&](const char* key, nlohmann::json v) {
    auto j = nlohmann::ordered_json::parse(done);
    if (v.is_discarded()) j.erase(key);
    else j[key] = v;
    return j.dump();
  };
  EXPECT_THAT(error_of(with("point", nlohmann::json::value_t::discarded)), HasSubstr("key \"point\": missing"));
  EXPECT_THAT(error_of(with("point", 0)), HasSubstr("key \"point\""));
  EXPECT_THAT(error_of(with("point", "4")), HasSubstr("key \"point\""));
  EXPECT_THAT(error_of(with("rows", -1)), HasSubstr("key \"rows\""));
  EXPECT_THAT(error_of(with("kind", "hover")), HasSubstr("key \"kind\""));
  EXPECT_THAT(error_of(with("phase", "sideways")), HasSubstr("key \"phase\""));
  EXPECT_THAT(error_of(with("counts_alpha", nullptr)), HasSubstr("key \"counts_alpha\""));
  EXPECT_THAT(error_of(with("type", "point_gone")), HasSubstr("key \"type\""));
  EXPECT_THAT(error_of(with("utc", 3)), HasSubstr("key \"utc\""));
  EXPECT_THAT(error_of("[1, 2]"), HasSubstr("expected a JSON object"));
  const std::string stop = line_of(every_event().back());
  auto stop_with = [&](const char* key, const char* v) {
    auto j = nlohmann::ordered_json::parse(stop);
    j[key] = v;
    return j.dump();
  };
  EXPECT_THAT(error_of(stop_with("cause", "gremlins")), HasSubstr("key \"cause\""));
  EXPECT_THAT(error_of(stop_with("outcome", "done")), HasSubstr("key \"outcome\""));
  auto st = nlohmann::ordered_json::parse(line_of(every_event()[6]));
  st["points_skipped"] = 4;
  EXPECT_THAT(error_of(st.dump()), HasSubstr("key \"points_skipped\""));
  EXPECT_THAT(error_of(line_of(every_event()[0]).replace(line_of(every_event()[0]).find("[6,"), 3, "[\"6\",")),
              HasSubstr("points[2]"));
}

TEST(Events, AFileWithABadLineNamesTheFileAndTheLine) {
  TempDir tmp("events-bad");
  const fs::path p = tmp / "events.jsonl";
  const auto events = every_event();
  test::write_file(p, line_of(events[0]) + "\n" + line_of(events[1]) + "\n{\"type\":\"paused\",\"utc\":\"u\"}\n");
  EventBus bus;
  size_t seen = 0;
  bus.subscribe([&](const Event&) { ++seen; });
  try {
    replay_events(p, bus);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(p.string() + ":3"));
    EXPECT_THAT(e.what(), HasSubstr("\"next_point\""));
  }
  EXPECT_EQ(seen, 2u);  // published in order up to the bad line
  // Not JSON at all: the line and column.
  test::write_file(p, line_of(events[0]) + "\n{\"type\": \n");
  EXPECT_THAT(test::error_of<InputError>([&] { replay_events(p, bus); }), HasSubstr(p.string() + ":2"));
  // A last line cut short (no newline) is a write in progress: left out.
  test::write_file(p, line_of(events[0]) + "\n{\"type\":\"run_st");
  EXPECT_EQ(replay_events(p, bus).events, 1u);
  // A line longer than the limit is refused without reading it whole.
  {
    std::ofstream f(p, std::ios::binary | std::ios::trunc);
    f << "{\"type\":\"warning\",\"utc\":\"u\",\"point\":null,\"message\":\"";
    const std::string block(1 << 20, 'x');
    for (size_t i = 0; i <= kMaxEventLineBytes / block.size(); ++i) f << block;
    f << "\"}\n";
  }
  EXPECT_THAT(test::error_of<InputError>([&] { replay_events(p, bus); }), HasSubstr("longer than"));
  // Not a regular file.
  EXPECT_THAT(test::error_of<InputError>([&] { replay_events(tmp.path(), bus); }), HasSubstr("regular file"));
}

// The engine's events as it published them, without the time they were written.
nlohmann::ordered_json without_utc(const Event& e) {
  auto j = to_json(e);
  j.erase("utc");
  return j;
}

TEST(Events, AReplayedRunPublishesWhatTheEngineDidLive) {
  TempDir tmp("events-replay");
  Bench bench(tmp / "run");
  EventLog log(tmp / "run" / "events.jsonl");
  std::vector<nlohmann::ordered_json> live;
  bench.bus.subscribe([&](const Event& e) {
    live.push_back(without_utc(e));
    log.write(e);
  });
  log.write_note("prompt", {{"id", "operator"}, {"text", "Who runs it?"}, {"kind", "text"}});
  // One warning on the way, as a re-measurement would give.
  bench.on_point_done([&](const PointDone& p) {
    if (p.point.index == 2) bench.bus.publish(Fault{Fault::Level::warning, p.point.index, "a note on point 3", {}});
  });
  const EngineResult r = bench.engine()->run();
  ASSERT_EQ(r.outcome, RunOutcome::completed) << r.reason;

  // Every line the engine wrote reads back to the very same line.
  std::istringstream in(test::read_file(tmp / "run" / "events.jsonl"));
  size_t lines = 0;
  for (std::string line; std::getline(in, line); ++lines) {
    const EventLine l = event_line_from_json(parse_json_text(line, "events.jsonl"), "events.jsonl");
    if (const auto* e = std::get_if<Event>(&l)) {
      EXPECT_EQ(to_json(*e).dump(), line);
    }
  }
  EXPECT_EQ(lines, live.size() + 1);

  EventBus replay;
  std::vector<nlohmann::ordered_json> replayed;
  size_t done = 0, started = 0;
  std::optional<RunStopped> stopped;
  std::optional<RunStarted> run_started;
  replay.subscribe([&](const Event& e) {
    replayed.push_back(without_utc(e));
    done += std::holds_alternative<PointDone>(e);
    started += std::holds_alternative<PointStarted>(e);
    if (const auto* s = std::get_if<RunStopped>(&e)) stopped = *s;
    if (const auto* s = std::get_if<RunStarted>(&e)) run_started = *s;
  });
  std::vector<std::string> notes;
  const ReplayCount c = replay_events(tmp / "run" / "events.jsonl", replay, [&](const Note& n) { notes.push_back(n.type); });
  EXPECT_EQ(c.events, live.size());
  EXPECT_EQ(c.notes, 1u);
  EXPECT_EQ(notes, std::vector<std::string>{"prompt"});
  EXPECT_EQ(replayed, live);  // the same events in the same order, value for value
  EXPECT_EQ(done, bench.plan.points);
  EXPECT_GE(started, bench.plan.points);
  ASSERT_TRUE(stopped);
  EXPECT_EQ(stopped->outcome, RunOutcome::completed);
  EXPECT_EQ(stopped->cause, StopCause::none);
  EXPECT_EQ(stopped->points_done, static_cast<int64_t>(bench.plan.points));
  ASSERT_TRUE(run_started);
  EXPECT_EQ(run_started->points.size(), bench.plan.points);
  EXPECT_EQ(run_started->points_total, bench.plan.points);
}

}  // namespace
}  // namespace fpss
