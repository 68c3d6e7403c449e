#include "stand/cli/help.h"

#include <algorithm>
#include <numeric>

namespace fpss::cli {

const std::vector<ExitCodeMeaning>& exit_code_table() {
  static const std::vector<ExitCodeMeaning> table = {
      {exit_code::ok, "ok"},
      {exit_code::failed, "the job failed (a run stopped or failed, a device, file system or catalogue refused)"},
      {exit_code::bad_input, "bad usage or bad input (an option, value or file; named in the message, nothing started)"},
      {exit_code::acceptance_failed, "acceptance failed (accept)"},
      {exit_code::acceptance_conditional, "acceptance conditional: within the guard band, no acceptance (accept)"},
  };
  return table;
}

std::string exit_codes_text() {
  std::string text = "\nExit codes:\n";
  for (const auto& e : exit_code_table()) text += "  " + std::to_string(e.code) + "  " + e.meaning + "\n";
  return text;
}

void examples(CLI::App* sub, const std::vector<std::string>& lines) {
  std::string text = exit_codes_text() + "\nExamples:\n";
  for (const auto& l : lines) text += "  " + l + "\n";
  sub->footer(text);
}

namespace {

// Optimal string alignment distance: insertions, deletions, substitutions, swaps of neighbours.
size_t distance(const std::string& a, const std::string& b) {
  const size_t n = a.size(), m = b.size();
  std::vector<std::vector<size_t>> d(n + 1, std::vector<size_t>(m + 1));
  for (size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (size_t i = 1; i <= n; ++i) {
    for (size_t j = 1; j <= m; ++j) {
      const size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[n][m];
}

std::string bare(const std::string& s) { return s.substr(s.find_first_not_of('-') == std::string::npos ? s.size() : s.find_first_not_of('-')); }

}  // namespace

std::string closest(const std::string& typed, const std::vector<std::string>& candidates) {
  const std::string t = bare(typed);
  if (t.empty()) return {};
  std::string best;
  size_t best_d = std::string::npos;
  for (const auto& c : candidates) {
    const size_t d = distance(t, bare(c));
    if (d < best_d) best_d = d, best = c;
  }
  // Close: at most a third of the word wrong (one edit in a short word, three at most).
  const size_t allowed = std::clamp<size_t>(t.size() / 3, 1, 3);
  if (best_d > 0 && best_d <= allowed) return best;
  // A start of exactly one name (--target for --target-sigma-arcsec).
  std::vector<std::string> starts;
  for (const auto& c : candidates) {
    if (t.size() >= 3 && bare(c).rfind(t, 0) == 0 && bare(c) != t) starts.push_back(c);
  }
  return starts.size() == 1 ? starts.front() : std::string();
}

const CLI::App* deepest_parsed(const CLI::App& app) {
  for (const CLI::App* s : app.get_subcommands()) {
    if (s->parsed()) return deepest_parsed(*s);
  }
  return &app;
}

std::string did_you_mean(const CLI::App& at, const std::vector<std::string>& unexpected, bool name_typed) {
  std::vector<std::string> options, commands;
  for (const CLI::App* a = &at; a != nullptr; a = a->get_parent()) {
    for (const CLI::Option* o : a->get_options()) {
      for (const auto& l : o->get_lnames()) options.push_back("--" + l);
    }
  }
  for (const CLI::App* s : at.get_subcommands([](const CLI::App*) { return true; })) {
    if (!s->get_name().empty()) commands.push_back(s->get_name());
  }
  for (const auto& word : unexpected) {
    if (word.rfind("--", 0) == 0) {
      const std::string typed = word.substr(0, word.find('='));
      const std::string hit = closest(typed, options);
      if (!hit.empty()) return "; " + (name_typed ? typed + ": " : "") + "did you mean " + hit + "?";
    } else if (!word.empty() && word[0] != '-') {
      const std::string hit = closest(word, commands);
      if (!hit.empty()) return "; " + (name_typed ? word + ": " : "") + "did you mean '" + hit + "'?";
    }
  }
  return {};
}

}  // namespace fpss::cli
