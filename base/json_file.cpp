#include "base/json_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <iterator>
#include <set>
#include <vector>

#include "base/errors.h"
#include "base/text_file.h"

namespace fpss {
namespace {

// An input iterator over the text that records how far the parser has read, so that errors found
// in the parser callback (which knows no positions) can name a line and column.
struct CountingIterator {
  using iterator_category = std::input_iterator_tag;
  using value_type = char;
  using difference_type = std::ptrdiff_t;
  using pointer = const char*;
  using reference = const char&;

  const char* p = nullptr;
  const char** furthest = nullptr;

  reference operator*() const { return *p; }
  CountingIterator& operator++() {
    ++p;
    if (p > *furthest) *furthest = p;
    return *this;
  }
  CountingIterator operator++(int) {
    CountingIterator old = *this;
    ++*this;
    return old;
  }
  bool operator==(const CountingIterator& o) const { return p == o.p; }
  bool operator!=(const CountingIterator& o) const { return p != o.p; }
};

std::string position(std::string_view text, const char* at) {
  size_t line = 1, col = 1;
  for (const char* c = text.data(); c < at; ++c) {
    if (*c == '\n') {
      ++line;
      col = 1;
    } else {
      ++col;
    }
  }
  return fmt::format("{}:{}", line, col);
}

}  // namespace

nlohmann::json parse_json_text(std::string_view text, const std::string& origin, int max_depth) {
  const char* furthest = text.data();
  // The keys seen so far in each open object (an empty set stands for an open array).
  std::vector<std::set<std::string>> open;
  std::vector<bool> is_object;
  // The lexer reads one character ahead: the last one it took is where the fault is.
  auto where = [&] { return fmt::format("{}:{}", origin, position(text, furthest > text.data() ? furthest - 1 : furthest)); };
  using E = nlohmann::json::parse_event_t;
  nlohmann::json::parser_callback_t cb = [&](int depth, E event, nlohmann::json& parsed) -> bool {
    switch (event) {
      case E::object_start:
      case E::array_start:
        if (depth >= max_depth) {
          throw InputError(fmt::format("{}: nested deeper than {} levels (docs/formats.md, Limits)", where(), max_depth));
        }
        open.emplace_back();
        is_object.push_back(event == E::object_start);
        break;
      case E::object_end:
      case E::array_end:
        if (!open.empty()) {
          open.pop_back();
          is_object.pop_back();
        }
        break;
      case E::key:
        if (!open.empty() && is_object.back()) {
          const std::string key = parsed.get<std::string>();
          if (!open.back().insert(key).second) {
            throw InputError(fmt::format("{}: key \"{}\" given twice in one object", where(), key));
          }
        }
        break;
      case E::value:
        break;
    }
    return true;
  };
  CountingIterator first{text.data(), &furthest}, last{text.data() + text.size(), &furthest};
  try {
    return nlohmann::json::parse(first, last, cb);
  } catch (const nlohmann::json::parse_error& e) {
    // The parser's own position (its byte count is 1-based and counts the end of input).
    const char* at = text.data() + std::min<size_t>(e.byte > 0 ? e.byte - 1 : 0, text.size());
    throw InputError(fmt::format("{}:{}: not valid JSON: {}", origin, position(text, at), e.what()));
  } catch (const nlohmann::json::exception& e) {
    // parse_error, and out_of_range for numbers beyond a double (1e400): both are bad files.
    throw InputError(fmt::format("{}: not valid JSON: {}", where(), e.what()));
  }
}

nlohmann::json read_json_file(const std::filesystem::path& path, std::string_view what, std::uintmax_t max_bytes) {
  return parse_json_text(read_text_file(path, what, max_bytes), path.string());
}

}  // namespace fpss
