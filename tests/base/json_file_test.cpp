// The one JSON reader of outside files: depth and size limits, duplicate keys, positions in messages.
#include "base/json_file.h"

#include <gtest/gtest.h>

#include <string>

#include "base/errors.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

const std::string kGood8 = "[1e-4, 5e-7, 3e-5, 3e-4, 3.4, -1e-4, 1e-4, 1.7]";

std::string parse_error(const std::string& text) {
  return test::error_of<InputError>([&] { parse_json_text(text, "f.json"); });
}

TEST(JsonFile, DeepNestingIsRefusedWithoutCrashing) {
  const std::string deep = std::string(200000, '[') + std::string(200000, ']');
  std::string m = parse_error(deep);
  EXPECT_NE(m.find("f.json:1:65: nested deeper than 64 levels"), std::string::npos) << m;
  m = parse_error("{\"a\":" + std::string(200000, '['));
  EXPECT_NE(m.find("nested deeper than 64 levels"), std::string::npos) << m;
  // 64 levels are fine.
  EXPECT_NO_THROW(parse_json_text(std::string(64, '[') + std::string(64, ']'), "f.json"));
  EXPECT_NE(parse_error(std::string(65, '[') + std::string(65, ']')).find("deeper"), std::string::npos);
}

TEST(JsonFile, DuplicateKeysNamedWithLineAndColumn) {
  std::string m = parse_error("{\n \"alpha\": " + kGood8 + ",\n \"alpha\": " + kGood8 + "\n}");
  EXPECT_NE(m.find("f.json:3:"), std::string::npos) << m;
  EXPECT_NE(m.find("key \"alpha\" given twice in one object"), std::string::npos) << m;
  // The same key in two different objects is not a duplicate.
  EXPECT_NO_THROW(parse_json_text(R"({"a": {"x": 1}, "b": {"x": 2}, "c": [{"x": 1}, {"x": 2}]})", "f.json"));
  m = parse_error(R"({"a": {"x": 1, "y": 2, "x": 3}})");
  EXPECT_NE(m.find("key \"x\" given twice"), std::string::npos) << m;
}

TEST(JsonFile, NumbersBeyondADoubleAndSyntaxErrors) {
  std::string m = parse_error("{\"alpha\": [1e400]}");
  EXPECT_NE(m.find("f.json:1:"), std::string::npos) << m;
  EXPECT_NE(m.find("not valid JSON"), std::string::npos) << m;
  m = parse_error("{\"alpha\": [1,}");
  EXPECT_NE(m.find("not valid JSON"), std::string::npos) << m;
}

TEST(JsonFile, ByteOrderMarkAccepted) {
  EXPECT_EQ(parse_json_text("\xEF\xBB\xBF{\"unit\": \"X\"}", "f.json").at("unit"), "X");
}

}  // namespace
}  // namespace fpss
