// INVESTIGATION.html (stand/report/investigation_page.h).
#include "stand/report/investigation_page.h"

#include <fmt/format.h>

#include <sstream>
#include <string>

#include "base/text_file.h"
#include "stand/report/report.h"

namespace fpss {
namespace {

using ojson = nlohmann::ordered_json;

std::string esc(const ojson& j) { return html_escape(j.is_string() ? j.get<std::string>() : j.dump()); }

std::string names(const ojson& list) {
  std::string s;
  for (const auto& v : list) s += (s.empty() ? "" : ", ") + (v.is_string() ? v.get<std::string>() : v.dump());
  return s.empty() ? "none" : s;
}

}  // namespace

void write_investigation_page(const std::filesystem::path& html_path, const ojson& inv) {
  std::ostringstream h;
  h << "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>Investigation</title>\n<style>body{font-family:"
       "sans-serif;max-width:1100px;margin:1em auto}table{border-collapse:collapse}td,th{border:1px solid #bbb;"
       "padding:2px 6px;text-align:left;vertical-align:top}th{background:#eee}</style></head><body>\n";
  h << "<h1>Sim-to-real investigation</h1>\n";
  // A verdict only for a diagnosis that was made; else why none was.
  if (inv.value("diagnosed", true)) {
    h << "<p id=verdict><b>" << esc(inv.value("verdict_sentence", std::string())) << "</b></p>\n";
  } else {
    h << "<p id=verdict><b>No diagnosis: " << esc(inv.value("no_diagnosis", std::string())) << "</b></p>\n";
  }
  h << "<p id=stop>Stopped: " << esc(inv.value("stop_reason", std::string())) << ": "
    << esc(inv.value("stop_sentence", std::string())) << "</p>\n";
  h << "<table><tr><th>cause</th><td>" << esc(inv.value("cause", std::string("none"))) << "</td></tr>";
  std::string causes;
  for (const auto& c : inv.value("causes", ojson::array())) {
    causes += (causes.empty() ? "" : "; ") + c.value("name", std::string()) + " " + c.value("params", ojson::object()).dump();
  }
  h << "<tr><th>causes and parameters</th><td><code>" << html_escape(causes.empty() ? "none" : causes) << "</code></td></tr>";
  std::string sets;
  for (const auto& a : inv.value("ambiguous", ojson::array())) sets += (sets.empty() ? "" : "; ") + names(a["members"]);
  h << "<tr><th>still ambiguous</th><td>" << html_escape(sets.empty() ? "none" : sets) << "</td></tr>";
  h << "<tr><th>neither named nor bounded</th><td>" << html_escape(names(inv.value("unbounded", ojson::array())))
    << "</td></tr>";
  const ojson bt = inv.value("bench_time_s", ojson::object());
  h << fmt::format("<tr><th>bench time</th><td>first run {:.0f} s, follow-ups {:.0f} s ({:.2f}x)</td></tr></table>\n",
                   bt.value("first", 0.0), bt.value("followups", 0.0), bt.value("followups_ratio", 0.0));
  h << "<h2>Steps</h2>\n<table><tr><th>#</th><th>run</th><th>why</th><th>diagnosis</th><th>separated</th></tr>\n";
  int k = 0;
  for (const auto& s : inv.value("steps", ojson::array())) {
    const ojson d = s.value("diagnosis", ojson::object());
    std::string diag = d.empty() ? "no diagnosis" + (s.contains("no_diagnosis") ? ": " + s.value("no_diagnosis", std::string()) : std::string())
                                 : fmt::format("{}: {} (ambiguous: {})", d.value("verdict", std::string()),
                                               d.value("cause", std::string()), names(d.value("ambiguous", ojson::array())));
    // A run that stopped short (a failed check, a device fault) says so beside its diagnosis.
    if (s.contains("stop")) diag = s.value("stop", std::string()) + "; " + diag;
    h << "<tr><td>" << ++k << "</td><td><code>" << esc(s.value("run", std::string())) << "</code></td><td>"
      << esc(s.value("why", std::string())) << "</td><td>" << html_escape(diag) << "</td><td>"
      << html_escape(names(s.value("separated", ojson::array()))) << "</td></tr>\n";
  }
  h << "</table>\n<h2>Candidates at the end</h2>\n<table><tr><th>effect</th><th>status</th><th>why</th></tr>\n";
  for (const auto& c : inv.value("candidates", ojson::array())) {
    h << "<tr><td>" << esc(c.value("name", std::string())) << "</td><td>" << esc(c.value("status", std::string()))
      << "</td><td>" << esc(c.value("why", std::string())) << "</td></tr>\n";
  }
  h << "</table>\n</body></html>\n";
  write_text_atomic(html_path, h.str());
}

}  // namespace fpss
