// fpss-stand msa: the fleet's measurement-system analysis (AIAG MSA, ANOVA) from the catalogue's calibrations and acceptances.
#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <random>

#include "base/errors.h"
#include "base/text_file.h"
#include "stand/acceptance/acceptance.h"
#include "stand/catalogue/catalogue.h"
#include "stand/catalogue/msa_study.h"
#include "stand/cli/catalogue_option.h"
#include "stand/cli/commands.h"
#include "stand/cli/emulated_bench.h"
#include "stand/cli/file_options.h"
#include "stand/cli/help.h"
#include "stand/report/msa_page.h"

namespace fpss::cli {

namespace {

// The tolerance of each kind of quantity from the acceptance limits: the mean residual's limit is
// one-sided with a natural zero (the tolerance is the limit), the calibrated angle's at the set
// points is the accuracy limit either side (twice it), accuracy's its own limit.
MsaTolerances tolerances_from(const AcceptanceLimits& l) {
  const std::string& file = l.origin;
  return {MsaTolerance{l.residual_mean_abs_arcsec.value, fmt::format("{}: residual_mean_abs_arcsec, one-sided from 0", file)},
          MsaTolerance{2 * l.accuracy_3sigma_arcsec.value, fmt::format("{}: accuracy_3sigma_arcsec either side (twice it)", file)},
          MsaTolerance{l.accuracy_3sigma_arcsec.value, fmt::format("{}: accuracy_3sigma_arcsec, one-sided from 0", file)}};
}

// A comma-separated list of names; an empty name is refused (CLI11's delimiter would drop it).
std::vector<std::string> split_list(const std::string& s, const char* option) {
  std::vector<std::string> out;
  size_t b = 0;
  while (b <= s.size() && !s.empty()) {
    const size_t e = std::min(s.find(',', b), s.size());
    if (e == b) throw InputError(fmt::format("{} {}: an empty name in the list", option, s));
    out.push_back(s.substr(b, e - b));
    b = e + 1;
  }
  return out;
}

// The study's runs, per stand (or per operator): every unit once per round, `repeats` rounds, each
// round's order drawn anew (seeded) so that a drift of the stand over the day does not follow the
// units (AIAG: randomise the order of measurement). Each job is a body of the console's POST
// /api/jobs, the list one of POST /api/jobs/batch; an operator's jobs name the operator, so their
// runs record who made them.
nlohmann::ordered_json msa_plan(const std::vector<std::string>& units, const std::vector<std::string>& appraisers,
                                MsaAppraisers by, int repeats, const std::string& procedure, uint64_t seed) {
  const bool by_operators = by == MsaAppraisers::operators;
  if (units.size() < 2 || appraisers.size() < 2) {
    throw InputError(fmt::format("msa plan: --units and --{} need at least two names each (a crossed study)",
                                 to_string(by)));
  }
  if (repeats < 2 || repeats > 10) throw InputError(fmt::format("--repeats {}: expected 2 to 10", repeats));
  if (units.size() * static_cast<size_t>(repeats) > 100) {
    throw InputError(fmt::format("msa plan: {} units x {} repeats is more than the 100 jobs a console queues",
                                 units.size(), repeats));
  }
  std::mt19937_64 rng(seed);
  nlohmann::ordered_json per_appraiser = nlohmann::ordered_json::array();
  for (const std::string& st : appraisers) {
    nlohmann::ordered_json jobs = nlohmann::ordered_json::array();
    for (int k = 1; k <= repeats; ++k) {
      std::vector<std::string> order = units;
      std::shuffle(order.begin(), order.end(), rng);
      for (const std::string& u : order) {
        // A stand's job leaves the operator to whoever runs it (the catalogue records it); `round`
        // is for the reader (the console ignores other keys).
        nlohmann::ordered_json job{{"kind", "run"}, {"procedure", procedure}, {"unit", u}, {"round", k}};
        if (by_operators) job["operator"] = st;
        jobs.push_back(std::move(job));
      }
    }
    per_appraiser.push_back({{by_operators ? "operator" : "stand", st}, {"jobs", jobs}});
  }
  const std::string list = to_string(by);  // "stands" or "operators"
  return {{"format", "fpss-stand msa-plan/1"}, {"units", units}, {list, appraisers}, {"repeats", repeats},
          {"procedure", procedure}, {"seed", seed}, {"runs", units.size() * appraisers.size() * static_cast<size_t>(repeats)},
          {list + "_jobs", per_appraiser}};
}

void add_msa_plan(CLI::App* msa, Runner& run) {
  struct Opts {
    std::string units, stands, operators, procedure = "discrete_grid.yaml", out;
    int repeats = 3;
    uint64_t seed = 1;
    FileOptions files;
  };
  auto o = std::make_shared<Opts>();
  auto* sub = msa->add_subcommand("plan", "Write a crossed study's runs (units x stands, or operators, x repeats) as "
                                          "console jobs, per stand or operator, in a randomised order per round");
  sub->add_option("--units", o->units, "the units, comma-separated")->required();
  auto* stands = sub->add_option("--stands", o->stands, "the stands, comma-separated");
  sub->add_option("--operators", o->operators, "instead of --stands: the operators, comma-separated (each job names "
                                               "its operator)")
      ->excludes(stands);
  sub->add_option("--repeats", o->repeats, "calibrations of each unit on each stand (2 to 10)")->capture_default_str();
  sub->add_option("--procedure", o->procedure, "the procedure each run does (a file of the console's procedures folder)")
      ->capture_default_str();
  sub->add_option("--seed", o->seed, "the order's seed")->capture_default_str()->check(seed_check());
  o->files.output(sub, "--out", o->out, "the plan (JSON): per stand, the jobs for POST /api/jobs/batch")->required();
  examples(sub, {"fpss-stand msa plan --units SN1,SN2,SN3 --stands S1,S2 --repeats 3 --out plan.json",
                 "fpss-stand msa plan --units SN1,SN2,SN3 --operators Ann,Bo --repeats 2 --out plan.json"});
  sub->callback([o, &run] {
    run = [o] {
      o->files.check();
      const bool by_operators = !o->operators.empty();
      if (!by_operators && o->stands.empty()) throw InputError("msa plan: --stands or --operators is required");
      const auto plan = msa_plan(split_list(o->units, "--units"),
                                 by_operators ? split_list(o->operators, "--operators") : split_list(o->stands, "--stands"),
                                 by_operators ? MsaAppraisers::operators : MsaAppraisers::stands, o->repeats,
                                 o->procedure, o->seed);
      write_text_atomic(o->out, plan.dump(1) + "\n");
      std::printf("%zu runs: %zu per %s; queue %s list with POST /api/jobs/batch (docs/console.md)\nwrote %s\n",
                  plan["runs"].get<size_t>(),
                  plan["runs"].get<size_t>() / plan[by_operators ? "operators" : "stands"].size(),
                  by_operators ? "operator" : "stand",
                  by_operators ? "an operator's" : "a stand's", o->out.c_str());
      return 0;
    };
  });
}

}  // namespace

void add_msa(CLI::App& app, Runner& run) {
  struct Opts {
    std::string db, runs_dir = "runs", units, stands, operators, appraisers = "stands", since, limits, out, report;
    FileOptions files;
  };
  auto o = std::make_shared<Opts>();
  auto* sub = app.add_subcommand(
      "msa", "Measurement-system analysis across the fleet: units x stands (or operators) x repeats from the "
             "catalogue, per quantity (AIAG MSA, ANOVA): EV, AV, interaction, GRR, PV, %GRR of the tolerance and of "
             "TV, ndc");
  add_catalogue_option(sub, o->db);
  sub->add_option("--runs-dir", o->runs_dir, "runs folder; the default catalogue is its stand.db")->capture_default_str();
  sub->add_option("--units", o->units, "the units (parts), comma-separated (default: every unit)");
  sub->add_option("--appraisers", o->appraisers, "what is crossed with the units: stands, or operators (the "
                                                 "runs' operators, on whichever stands)")
      ->check(CLI::IsMember({"stands", "operators"}))
      ->capture_default_str();
  sub->add_option("--stands", o->stands, "the stands, comma-separated (default: every stand; "
                                         "'emulator' for emulated runs without a stand file)");
  sub->add_option("--operators", o->operators, "the operators, comma-separated (default: every operator; "
                                               "'unnamed' for runs that named none)");
  sub->add_option("--since", o->since, "only records from this ISO 8601 date or time on");
  o->files.input(sub, "--limits", o->limits, "acceptance limits file: the tolerances (default: the shipped limits)");
  o->files.output(sub, "--out", o->out, "the study as JSON (MSA.json; required)");
  o->files.output(sub, "--report", o->report, "the study as a page (MSA.html)");
  examples(sub, {"fpss-stand msa --catalogue postgresql://fleet@db/fpss --out msa.json --report msa.html",
                 "fpss-stand msa --runs-dir runs --units SN1,SN2,SN3 --appraisers operators --operators Ann,Bo "
                 "--stands S1 --since 2026-01-01 --out msa.json"});
  add_msa_plan(sub, run);
  sub->callback([o, sub, &run] {
    if (sub->get_subcommands().size() > 0) return;  // msa plan set the runner
    run = [o] {
      if (o->out.empty()) throw InputError("msa: --out MSA.json is required");
      o->files.check();
      MsaSelection sel{split_list(o->units, "--units"), split_list(o->stands, "--stands"), o->since,
                       split_list(o->operators, "--operators"),
                       o->appraisers == "operators" ? MsaAppraisers::operators : MsaAppraisers::stands};
      const AcceptanceLimits limits = load_acceptance_limits(o->limits.empty() ? default_limits_path() : std::filesystem::path(o->limits));
      const std::string url = catalogue_url(o->db, o->runs_dir);
      const auto cat = open_catalogue(url, Catalogue::Mode::read_only);
      const MsaStudy s = msa_study(*cat, sel, tolerances_from(limits));
      write_text_atomic(o->out, s.to_json(url, sel).dump(1) + "\n");
      if (!o->report.empty()) write_text_atomic(o->report, msa_html(s, url));
      std::printf("%zu units x %zu %s x %zu repeats\n", s.units.size(), s.appraisers.size(), to_string(s.appraised_by),
                  s.repeats);
      for (const MsaQuantity& q : s.quantities) std::printf("%-34s %s\n", q.name.c_str(), msa_verdict(q.result).c_str());
      for (const auto& [q, why] : s.skipped) std::printf("%-34s not studied: %s\n", q.c_str(), why.c_str());
      std::printf("wrote %s\n", o->out.c_str());
      return 0;
    };
  });
}

}  // namespace fpss::cli
