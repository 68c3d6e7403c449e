// The run folder's control channel: control.json read with limits, and its changes mapped onto
// RunControl (pause flips, abort once, answers), as a run sees them. < 2 s.
#include <gtest/gtest.h>

#include "stand/session/control_channel.h"
#include "tests/support/test_support.h"

namespace {

using namespace fpss;
using namespace fpss::test;

TEST(ControlChannel, ReadsOnlyASmallRegularJsonFile) {
  TempDir t;
  EXPECT_FALSE(read_control(t.path()));
  t.write("control.json", "not json");
  EXPECT_FALSE(read_control(t.path()));
  t.write("control.json", std::string(kMaxControlFileBytes + 1, ' '));
  EXPECT_FALSE(read_control(t.path()));
  fs::remove(t / "control.json");
  t.write("elsewhere.json", R"({"abort": true})");
  fs::create_symlink(t / "elsewhere.json", t / "control.json");
  EXPECT_FALSE(read_control(t.path())) << "a link is not followed";
  fs::remove(t / "control.json");
  t.write("control.json", R"({"pause": true, "abort": "yes", "answers": {"serial": "X1", "n": 3}})");
  const auto c = read_control(t.path());
  ASSERT_TRUE(c);
  EXPECT_TRUE(c->pause);
  EXPECT_FALSE(c->abort) << "a non-boolean is ignored";
  EXPECT_EQ(c->answers.size(), 1u);
  EXPECT_EQ(c->answers.at("serial"), "X1");
}

TEST(ControlChannel, ChangesActOnTheRunControl) {
  TempDir t;
  ControlRequest old;
  old.abort = true;  // left by an earlier session: history, not a request
  write_control(t.path(), old);
  RunControl rc;
  ControlPoller p(t.path(), rc);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_FALSE(rc.abort.load());
  EXPECT_FALSE(read_control(t.path())->abort) << "the channel starts clean";
  ControlRequest c;
  c.pause = true;
  write_control(t.path(), c);
  EXPECT_TRUE(wait_until([&] { return rc.pause.load(); }, 5));
  rc.pause = false;  // another pauser (a key, a signal) resumes: the file does not undo it
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_FALSE(rc.pause.load());
  c.answers["serial"] = "FPSS-1";
  write_control(t.path(), c);
  EXPECT_EQ(p.wait_answer("serial").value_or(""), "FPSS-1");
  c.abort = true;
  write_control(t.path(), c);
  EXPECT_TRUE(wait_until([&] { return rc.abort.load(); }, 5));
  EXPECT_EQ(rc.signal.load(), 0) << "an operator's abort, not a signal's";
  EXPECT_FALSE(p.wait_answer("never"));
}

}  // namespace
