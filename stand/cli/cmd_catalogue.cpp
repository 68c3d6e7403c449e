// fpss-stand runs / history / catalogue rebuild / catalogue copy: read the catalogue as a table or as JSON, re-index run folders into it, copy it to another backend.
#include <fmt/format.h>

#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/errors.h"
#include "base/json_file.h"
#include "calib/compare.h"
#include "stand/catalogue/run_file.h"
#include "stand/catalogue/catalogue.h"
#include "stand/catalogue/copy.h"
#include "stand/catalogue/rebuild.h"
#include "stand/cli/catalogue_option.h"
#include "stand/cli/commands.h"
#include "stand/cli/help.h"
#include "stand/cli/run_lookup.h"
#include "stand/report/run_summary.h"

namespace fpss::cli {
namespace {

struct DbOpts {
  std::string runs_dir = "runs";
  std::string db;  // overrides runs_dir
  bool json = false;

  const CLI::Option* runs_dir_option = nullptr;  // runs, history: an explicit --runs-dir names the catalogue

  std::string url() const {
    if (runs_dir_option != nullptr && runs_dir_option->count() > 0) return Catalogue::default_path(runs_dir).string();
    if (runs_dir_option != nullptr && chosen_catalogue(db).empty()) return default_catalogue();
    return catalogue_url(db, runs_dir);
  }

  // Nothing named (runs, history): runs/stand.db, else the catalogue found below this folder (the
  // demo's), else an error that says where catalogues are made.
  std::string default_catalogue() const {
    const std::filesystem::path here = Catalogue::default_path(runs_dir);
    if (std::filesystem::exists(here)) return here.string();
    if (const auto found = find_runs_dir_nearby(runs_dir)) {
      note_found_runs_dir(runs_dir, *found);
      return Catalogue::default_path(found->dir).string();
    }
    throw InputError(fmt::format("{}: no catalogue there (no run has been recorded with it), nor below this folder\n"
                                 "hint: a run records into RUNS_DIR/stand.db: give --runs-dir RUNS_DIR as the run had "
                                 "it (scripts/demo: build/demo/runs), or --catalogue URL",
                                 here.string()));
  }
};

// `exclusive`: --runs-dir only says where the default catalogue is (runs, history), so giving both
// is a mistake; rebuild reads the folders of --runs-dir into --catalogue.
void add_db_options(CLI::App* sub, DbOpts& o, bool exclusive = true) {
  auto* dir = sub->add_option("--runs-dir", o.runs_dir, "runs folder; the default catalogue is its stand.db")
                  ->capture_default_str();
  auto* db = add_catalogue_option(sub, o.db);
  if (exclusive) {
    dir->excludes(db);
    o.runs_dir_option = dir;  // over FPSS_CATALOGUE too: the user named the folder
  }
  sub->add_flag("--json", o.json, "print JSON instead of a table");
}

// Columns padded to their widest cell; the last column is not padded.
void print_table(const std::vector<std::string>& header, const std::vector<std::vector<std::string>>& rows) {
  std::vector<size_t> w(header.size());
  for (size_t c = 0; c < header.size(); ++c) w[c] = header[c].size();
  for (const auto& r : rows) {
    for (size_t c = 0; c < r.size() && c < w.size(); ++c) w[c] = std::max(w[c], r[c].size());
  }
  auto line = [&](const std::vector<std::string>& cells) {
    std::string out;
    for (size_t c = 0; c < cells.size(); ++c) {
      out += c + 1 == cells.size() ? cells[c] : fmt::format("{:<{}}  ", cells[c], w[c]);
    }
    while (!out.empty() && out.back() == ' ') out.pop_back();
    std::printf("%s\n", out.c_str());
  };
  line(header);
  for (const auto& r : rows) line(r);
}

std::string outcome_text(const RunRecord& r) {
  if (r.stale()) return fmt::format("{} (stale: pid {} gone)", r.outcome_name(), r.pid);
  return r.outcome_name();
}

// A text that may be missing: null when it is.
nlohmann::json text_or_null(const std::optional<std::string>& s) {
  return s ? nlohmann::json(*s) : nlohmann::json(nullptr);
}

nlohmann::json run_json(const RunRecord& r) {
  return {{"run_id", r.run_id}, {"unit", r.unit}, {"procedure", r.procedure}, {"procedure_hash", r.procedure_hash},
          {"started_utc", r.started_utc}, {"ended_utc", text_or_null(r.ended_utc)},
          {"outcome", r.outcome_name()}, {"stale", r.stale()},
          {"run_dir", r.run_dir}, {"emulated", r.emulated}, {"stand", r.stand}, {"host", r.host},
          {"operator", r.operator_name},
          {"software_version", r.software_version}, {"resumes", r.resumes}};
}

// What the run folder adds to the catalogue's row: a live run's progress (its journal), an
// acceptance's verdict (run.json). Nothing when the folder is gone or unreadable.
struct FolderStatus {
  int64_t done = 0, total = 0;
  std::string verdict;  // "pass" / "fail" for an acceptance, "" otherwise
};
FolderStatus folder_status(const RunRecord& r) {
  FolderStatus st;
  try {
    const RunFile run = read_run_file(r.run_dir);
    st.total = run.points.total;
    st.verdict = acceptance_verdict(run).value_or("");
    st.done = journal_points(r.run_dir);
  } catch (const std::exception&) {
    // the folder moved or is being written: the catalogue's row alone
  }
  return st;
}

std::string status_text(const RunRecord& r, const FolderStatus& st) {
  if (r.running() && !r.stale()) return fmt::format("running {}/{} points (pid {})", st.done, st.total, r.pid);
  return outcome_text(r);
}

int list_runs(const DbOpts& o, const std::string& unit, size_t limit) {
  const auto catp = open_catalogue(o.url(), Catalogue::Mode::read_only);
  const Catalogue& cat = *catp;
  RunFilter f;
  if (!unit.empty()) f.unit = unit;
  f.limit = limit;
  const auto runs = cat.list_runs(f);
  if (o.json) {
    nlohmann::json j = nlohmann::json::array();
    for (const auto& r : runs) {
      const FolderStatus st = folder_status(r);
      nlohmann::json row = run_json(r);
      row["points"] = {{"done", st.done}, {"total", st.total}};
      row["verdict"] = st.verdict.empty() ? nlohmann::json(nullptr) : nlohmann::json(st.verdict);
      j.push_back(std::move(row));
    }
    std::printf("%s\n", j.dump(1).c_str());
    return 0;
  }
  if (runs.empty()) {
    std::fprintf(stderr, "no runs%s in %s\n", unit.empty() ? "" : fmt::format(" of unit {}", unit).c_str(),
                 cat.location().c_str());
    return 0;
  }
  std::vector<std::vector<std::string>> rows;
  for (const auto& r : runs) {
    const FolderStatus st = folder_status(r);
    rows.push_back({r.run_id, r.unit, r.procedure, r.started_utc, r.ended_utc.value_or("-"),
                    r.emulated ? "emulated" : (r.stand.empty() ? "bench" : r.stand),
                    st.verdict.empty() ? "-" : st.verdict, status_text(r, st)});
  }
  print_table({"RUN", "UNIT", "PROCEDURE", "STARTED (UTC)", "ENDED (UTC)", "BENCH", "VERDICT", "OUTCOME"}, rows);
  return 0;
}

// One line of a unit's history, with the change against the previous calibration
// (transfer functions compared at equal counts) and the flag when it exceeds the limit; the
// table and JSON below print those fields once they are filled.
struct HistoryEntry {
  CalibrationRecord cal;
  std::optional<double> change_arcsec;  // vs the previous entry; empty for the first
  bool flagged = false;                 // change beyond the history limit
  std::optional<double> change_offset_removed_arcsec;  // the same with the null shift taken out
};

std::string source_text(const CalibrationRecord& c) {
  if (c.source == "run") return "run " + c.source_ref;
  return "import " + c.source_ref;
}

std::string opt_num(const std::optional<double>& v, int decimals) {
  return v ? fmt::format("{:.{}f}", *v, decimals) : "-";
}

// "0.26 +- 0.20" (mean |residual| +- sd), the Table 1 form; "-" for what is not known.
std::string mean_sd_text(const std::optional<AxisResidualStats>& s) {
  if (!s || !s->mean_abs_arcsec) return "-";
  return s->sd_arcsec ? fmt::format("{:.2f} +- {:.2f}", *s->mean_abs_arcsec, *s->sd_arcsec)
                      : fmt::format("{:.2f}", *s->mean_abs_arcsec);
}

std::string range_text(const std::optional<AxisResidualStats>& s) {
  if (!s || !s->range_lo_deg || !s->range_hi_deg) return "-";
  return fmt::format("{:+.2f}..{:+.2f}", *s->range_lo_deg, *s->range_hi_deg);
}

nlohmann::json history_json(const std::string& serial, const Catalogue& cat, const std::vector<HistoryEntry>& h) {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& e : h) {
    const auto& c = e.cal;
    nlohmann::json j = {{"id", c.id}, {"date", c.date_utc}, {"recorded_utc", c.recorded_utc},
                        {"source", c.source}, {"source_ref", c.source_ref}, {"run_id", text_or_null(c.run_id)},
                        {"label", c.label}, {"method", c.method},
                        {"residuals",
                         {{"pitch", c.pitch ? c.pitch->to_json() : nlohmann::json(nullptr)},
                          {"yaw", c.yaw ? c.yaw->to_json() : nlohmann::json(nullptr)}}},
                        {"coefficients", c.coefficients}};
    if (e.change_arcsec) {
      j["change_arcsec"] = *e.change_arcsec;
      j["flagged"] = e.flagged;
      if (e.change_offset_removed_arcsec) j["change_offset_removed_arcsec"] = *e.change_offset_removed_arcsec;
    }
    list.push_back(std::move(j));
  }
  return {{"unit", serial}, {"db", cat.location()}, {"calibrations", list}};
}

void print_history(const std::string& serial, const Catalogue& cat, const std::vector<HistoryEntry>& h) {
  std::printf("unit %s: %zu calibration%s in %s (residuals in arcsec: mean |r| +- sd, max; range in deg)\n",
              serial.c_str(), h.size(), h.size() == 1 ? "" : "s", cat.location().c_str());
  bool any_change = false;
  for (const auto& e : h) any_change |= e.change_arcsec.has_value();
  std::vector<std::string> header = {"ID",        "DATE",     "SOURCE",   "LABEL",    "METHOD",
                                     "PITCH MEAN", "PITCH MAX", "PITCH N", "PITCH RANGE",
                                     "YAW MEAN",  "YAW MAX",  "YAW N",    "YAW RANGE"};
  if (any_change) header.push_back("CHANGE");
  std::vector<std::vector<std::string>> rows;
  for (const auto& e : h) {
    const auto& c = e.cal;
    auto n = [](const std::optional<AxisResidualStats>& s) {
      return s && s->points ? std::to_string(*s->points) : std::string("-");
    };
    std::vector<std::string> row = {std::to_string(c.id),
                                    c.date_utc,
                                    source_text(c),
                                    c.label.empty() ? "-" : c.label,
                                    c.method.empty() ? "-" : c.method,
                                    mean_sd_text(c.pitch),
                                    opt_num(c.pitch ? c.pitch->max_abs_arcsec : std::nullopt, 2),
                                    n(c.pitch),
                                    range_text(c.pitch),
                                    mean_sd_text(c.yaw),
                                    opt_num(c.yaw ? c.yaw->max_abs_arcsec : std::nullopt, 2),
                                    n(c.yaw),
                                    range_text(c.yaw)};
    if (any_change) {
      row.push_back(e.change_arcsec ? fmt::format("{:.2f}{}", *e.change_arcsec, e.flagged ? " CHANGED" : "")
                                    : "-");
    }
    rows.push_back(std::move(row));
  }
  print_table(header, rows);
}

// Each calibration against the one before it (calib/compare.h): the largest |B - A| of either
// axis over the counts the earlier one maps into +-0.35 deg; flagged beyond the limit.
void fill_changes(std::vector<HistoryEntry>& h, double limit_arcsec) {
  for (size_t i = 1; i < h.size(); ++i) {
    try {
      const auto prev = parse_coefficients(h[i - 1].cal.coefficients, fmt::format("calibration {}", h[i - 1].cal.id));
      const auto cur = parse_coefficients(h[i].cal.coefficients, fmt::format("calibration {}", h[i].cal.id));
      const DriftCheck d = check_drift(prev, cur, limit_arcsec);
      h[i].change_arcsec = d.worst_arcsec;
      h[i].change_offset_removed_arcsec = d.worst_shape_arcsec;
      h[i].flagged = d.flagged;
    } catch (const InputError& e) {  // a set that cannot be compared: say so, keep listing
      std::fprintf(stderr, "note: calibration %lld not compared with the previous one: %s\n",
                   static_cast<long long>(h[i].cal.id), e.what());
    }
  }
}

int show_history(const DbOpts& o, const std::string& serial, double limit_arcsec) {
  if (!(limit_arcsec > 0)) throw InputError(fmt::format("--limit-arcsec {}: must be positive", limit_arcsec));
  const auto catp = open_catalogue(o.url(), Catalogue::Mode::read_only);
  const Catalogue& cat = *catp;
  std::vector<HistoryEntry> h;
  for (auto& c : cat.unit_history(serial)) h.push_back({std::move(c), std::nullopt, false, std::nullopt});
  if (h.empty()) {
    const std::string why = cat.has_unit(serial)
                                ? fmt::format("unit {} is in {} ({} runs) but has no calibration yet", serial,
                                              cat.location(), cat.list_runs({.unit = serial, .limit = 0}).size())
                                : fmt::format("no unit {} in {} (units there: {})", serial, cat.location(),
                                              [&] {
                                                std::string u;
                                                for (const auto& s : cat.units()) u += (u.empty() ? "" : ", ") + s;
                                                return u.empty() ? std::string("none") : u;
                                              }());
    throw InputError(why);
  }
  fill_changes(h, limit_arcsec);
  const HistoryEntry& latest = h.back();
  if (o.json) {
    nlohmann::json j = history_json(serial, cat, h);
    j["limit_arcsec"] = limit_arcsec;
    j["latest_flagged"] = latest.flagged;
    std::printf("%s\n", j.dump(1).c_str());
  } else {
    print_history(serial, cat, h);
    if (latest.change_arcsec) {
      std::printf("latest (%lld, %s) vs previous: %.2f arcsec (%.2f with the null shift removed), limit %g: %s\n",
                  static_cast<long long>(latest.cal.id), latest.cal.date_utc.c_str(), *latest.change_arcsec,
                  latest.change_offset_removed_arcsec.value_or(0.0), limit_arcsec,
                  latest.flagged ? "CHANGED beyond the limit" : "within the limit");
    }
  }
  return 0;
}

int rebuild(const DbOpts& o) {
  if (!std::filesystem::is_directory(o.runs_dir)) {
    throw InputError(fmt::format("--runs-dir {}: not a folder", o.runs_dir));
  }
  const auto catp = open_catalogue(o.url());
  Catalogue& cat = *catp;
  const RebuildReport r = rebuild_catalogue(cat, o.runs_dir);
  for (const auto& s : r.skipped) std::fprintf(stderr, "fpss-stand catalogue rebuild: skipped %s\n", s.c_str());
  if (o.json) {
    const nlohmann::json j{{"catalogue", cat.location()}, {"folders", r.folders},
                           {"runs_added", r.runs_added}, {"runs_updated", r.runs_updated},
                           {"operators_named", r.operators_named},
                           {"calibrations_added", r.calibrations_added}, {"acceptances_added", r.acceptances_added},
                           {"skipped", r.skipped}};
    std::printf("%s\n", j.dump(1).c_str());
  } else {
    std::printf("%s: %d run folders; added %d runs, %d calibrations, %d acceptances; updated %d runs%s; skipped %zu\n",
                cat.location().c_str(), r.folders, r.runs_added, r.calibrations_added, r.acceptances_added,
                r.runs_updated,
                r.operators_named ? fmt::format("; named the operator of {} runs", r.operators_named).c_str() : "",
                r.skipped.size());
  }
  return r.skipped.empty() ? 0 : 1;
}

struct CopyOpts {
  std::string from, to;
  bool json = false;
};

int copy(const CopyOpts& o) {
  const auto from = open_catalogue(o.from, Catalogue::Mode::read_only);
  const auto to = open_catalogue(o.to);
  const CopyReport r = copy_catalogue(*from, *to);
  if (o.json) {
    const nlohmann::json j{{"from", from->location()}, {"to", to->location()}, {"units_added", r.units_added},
                           {"runs_seen", r.runs_seen}, {"runs_added", r.runs_added},
                           {"calibrations_seen", r.calibrations_seen}, {"calibrations_added", r.calibrations_added},
                           {"acceptances_seen", r.acceptances_seen}, {"acceptances_added", r.acceptances_added}};
    std::printf("%s\n", j.dump(1).c_str());
  } else {
    std::printf("%s -> %s: added %d units, %d of %d runs, %d of %d calibrations, %d of %d acceptances\n",
                from->location().c_str(), to->location().c_str(), r.units_added, r.runs_added, r.runs_seen,
                r.calibrations_added, r.calibrations_seen, r.acceptances_added, r.acceptances_seen);
  }
  return 0;
}

}  // namespace

void add_catalogue(CLI::App& app, Runner& run) {
  auto* cat = app.add_subcommand("catalogue", "Maintain the catalogue");
  cat->require_subcommand(1);
  examples(cat, {"fpss-stand catalogue rebuild --runs-dir runs", "fpss-stand catalogue copy --from runs/stand.db --to copy.db"});
  {
    auto o = std::make_shared<DbOpts>();
    auto* sub = cat->add_subcommand("rebuild", "Re-index every run folder (run.json, calibrations, acceptance) "
                                               "into the catalogue (either backend); idempotent");
    add_db_options(sub, *o, false);
    examples(sub, {"fpss-stand catalogue rebuild --runs-dir runs",
                   "fpss-stand catalogue rebuild --runs-dir runs --catalogue postgresql://stand@db.lab/fpss?sslmode=require"});
    sub->callback([o, &run] { run = [o] { return rebuild(*o); }; });
  }
  {
    auto o = std::make_shared<CopyOpts>();
    auto* sub = cat->add_subcommand("copy", "Copy every record of one catalogue into another (e.g. SQLite to "
                                            "PostgreSQL); idempotent");
    sub->add_option("--from", o->from, "source catalogue URL (sqlite:PATH, PATH or postgresql://...)")->required();
    sub->add_option("--to", o->to, "target catalogue URL (created or upgraded when needed)")->required();
    sub->add_flag("--json", o->json, "print the counts as JSON");
    examples(sub, {"fpss-stand catalogue rebuild --runs-dir runs",
                   "fpss-stand catalogue copy --from runs/stand.db --to sqlite:copy.db --json"});
    sub->callback([o, &run] { run = [o] { return copy(*o); }; });
  }
  {
    struct Opts {
      DbOpts db;
      std::string unit;
      size_t limit = 0;
    };
    auto o = std::make_shared<Opts>();
    auto* sub = app.add_subcommand("runs", "List the runs recorded in the catalogue, most recent first");
    add_db_options(sub, o->db);
    sub->add_option("--unit", o->unit, "only the runs of this unit (serial)");
    sub->add_option("--limit", o->limit, "at most this many runs (0: all)")->capture_default_str();
    examples(sub, {"fpss-stand runs --runs-dir runs --limit 10", "fpss-stand runs --runs-dir runs --unit FPSS1-SN042"});
    sub->callback([o, &run] { run = [o] { return list_runs(o->db, o->unit, o->limit); }; });
  }
  {
    struct Opts {
      DbOpts db;
      std::string serial;
      double limit_arcsec = kDefaultDriftLimitArcsec;
    };
    auto o = std::make_shared<Opts>();
    auto* sub = app.add_subcommand("history", "List one unit's calibrations over time with their residuals");
    sub->add_option("SERIAL", o->serial, "the unit's serial number")->required();
    add_db_options(sub, o->db);
    sub->add_option("--limit-arcsec", o->limit_arcsec,
                    "flag a calibration that differs from the previous by more than this (max |B - A|, +-0.35 deg)")
        ->capture_default_str();
    examples(sub, {"fpss-stand import calib/data/published/a-6-fpss1.json --unit FPSS1 --date 1980-08-27 --runs-dir runs",
                   "fpss-stand history FPSS1 --runs-dir runs"});
    sub->callback([o, &run] { run = [o] { return show_history(o->db, o->serial, o->limit_arcsec); }; });
  }
}

}  // namespace fpss::cli
