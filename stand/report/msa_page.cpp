#include "stand/report/msa_page.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "stand/report/report.h"

namespace fpss {

std::string msa_html(const MsaStudy& s, const std::string& catalogue) {
  std::string h =
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>Measurement-system analysis"
      "</title>\n<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
      "td,th{border:1px solid #ccc;padding:.25em .5em;text-align:right}th.l,td.l{text-align:left}</style>\n"
      "</head>\n<body>\n<h1>Measurement-system analysis</h1>\n";
  const bool by_operators = s.appraised_by == MsaAppraisers::operators;
  h += fmt::format("<p>AIAG MSA 4th edition, ANOVA method (crossed, the interaction kept), from the catalogue {}: "
                   "{} units ({}) &times; {} {} ({}) &times; {} repeats (the latest of each unit {}); "
                   "{} calibrations used, {} records left out by the selection.</p>\n",
                   html_escape(catalogue), s.units.size(), html_escape(fmt::format("{}", fmt::join(s.units, ", "))),
                   s.appraisers.size(), to_string(s.appraised_by),
                   html_escape(fmt::format("{}", fmt::join(s.appraisers, ", "))), s.repeats,
                   by_operators ? "by each operator, on whichever stand: the appraisers are the operators"
                                : "on each stand",
                   s.records_used, s.records_left_out);
  h += "<table id=\"msa\">\n<tr><th class=\"l\">quantity</th><th>EV</th><th>AV</th><th>interaction</th><th>GRR</th>"
       "<th>PV</th><th>TV</th><th>tolerance</th><th>%GRR of tolerance</th><th>%GRR of TV</th><th>ndc</th>"
       "<th class=\"l\">reading</th></tr>\n";
  for (const MsaQuantity& q : s.quantities) {
    const GaugeRr& r = q.result;
    h += fmt::format("<tr><td class=\"l\">{}</td><td>{:.4f}</td><td>{:.4f}</td><td>{:.4f}</td><td>{:.4f}</td><td>{:.4f}</td>"
                     "<td>{:.4f}</td><td>{}</td><td>{}</td><td>{:.1f}</td><td>{}</td><td class=\"l\">{}</td></tr>\n",
                     html_escape(q.name), r.ev, r.av, r.interaction_sd, r.grr, r.pv, r.tv,
                     q.tolerance ? fmt::format("{:.3f}", q.tolerance->value) : "&ndash;",
                     r.grr_percent_tolerance ? fmt::format("{:.1f}", *r.grr_percent_tolerance) : "&ndash;",
                     r.grr_percent_tv, r.ndc, html_escape(msa_verdict(r)));
  }
  h += "</table>\n<p>Standard deviations in arcsec; %GRR of the tolerance is 100 &times; 6 GRR / tolerance.</p>\n";
  if (!s.skipped.empty()) {
    h += "<h2>Not studied</h2>\n<ul>\n";
    for (const auto& [q, why] : s.skipped) h += fmt::format("<li>{}: {}</li>\n", html_escape(q), html_escape(why));
    h += "</ul>\n";
  }
  h += "<h2>Tolerances</h2>\n<ul>\n";
  for (const MsaQuantity& q : s.quantities) {
    if (q.tolerance) h += fmt::format("<li>{}: {}</li>\n", html_escape(q.name), html_escape(q.tolerance->source));
  }
  h += "</ul>\n</body>\n</html>\n";
  return h;
}

}  // namespace fpss
