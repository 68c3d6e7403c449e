// A check on program output and generated pages: that parts of a text appear, in a given order.
#pragma once
#include <gtest/gtest.h>

#include <initializer_list>
#include <string>

namespace fpss::test {

// Whether each part occurs in `text` and each one's first occurrence comes after the previous
// part's; on failure, which part is missing or out of order, and the text.
inline ::testing::AssertionResult appear_in_order(const std::string& text, std::initializer_list<std::string> parts) {
  size_t previous = 0;
  const std::string* previous_part = nullptr;
  for (const auto& part : parts) {
    const size_t at = text.find(part);
    if (at == std::string::npos) return ::testing::AssertionFailure() << "no \"" << part << "\" in:\n" << text;
    if (previous_part && at <= previous) {
      return ::testing::AssertionFailure() << "\"" << part << "\" comes before \"" << *previous_part << "\" in:\n"
                                           << text;
    }
    previous = at;
    previous_part = &part;
  }
  return ::testing::AssertionSuccess();
}

}  // namespace fpss::test
