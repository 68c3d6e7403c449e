// fpss-stand accept / compare / import: acceptance of a unit, comparison of calibrations, imports into the catalogue.
#include <fmt/format.h>
#include <spawn.h>
#include <sys/wait.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <regex>
#include <string>

#include <nlohmann/json.hpp>

#include "calib/coefficients.h"
#include "calib/compare.h"
#include "calib/errors.h"
#include "procedures/catalogue.h"
#include "stand/commands.h"

extern char** environ;

namespace fpss::cli {
namespace fs = std::filesystem;
namespace {

fs::path catalogue_path(const std::string& db, const std::string& runs_dir) {
  return db.empty() ? Catalogue::default_path(runs_dir) : fs::path(db);
}

// A calibration named on the command line: a coefficient file (calibration.json is one), a
// published set ("a-6-fpss1"), or "cal:ID" for a calibration in the catalogue.
struct NamedSet {
  CoefficientSet set;
  std::string name;
};

NamedSet resolve_calibration(const std::string& arg, const fs::path& db) {
  if (arg.rfind("cal:", 0) == 0) {
    int64_t id = 0;
    try {
      size_t used = 0;
      id = std::stoll(arg.substr(4), &used);
      if (used != arg.size() - 4) throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
      throw InputError(fmt::format("{}: expected cal:ID with a numeric catalogue id", arg));
    }
    const Catalogue cat(db, Catalogue::Mode::read_only);
    const auto rec = cat.find_calibration(id);
    if (!rec) throw InputError(fmt::format("{}: no calibration {} in {}", arg, id, db.string()));
    NamedSet n{parse_coefficients(rec->coefficients, fmt::format("{} calibration {}", db.string(), id)), {}};
    n.name = fmt::format("{} calibration {} of {} ({}{})", db.string(), id, rec->unit, rec->date_utc,
                         rec->label.empty() ? "" : ", " + rec->label);
    return n;
  }
  if (fs::exists(arg)) return {load_coefficients(arg), arg};
  for (const auto& name : published_names()) {
    if (name == arg) return {load_published(name), fmt::format("published {}", name)};
  }
  throw InputError(fmt::format("{}: no such coefficient file, published set (a-1-fpss1 .. a-7-fpss2) or cal:ID", arg));
}

// Runs gnuplot on `script` without a shell; returns its exit status (-1 when it cannot start).
int run_gnuplot(const fs::path& script) {
  const std::string prog = "gnuplot", arg = script.string();
  char* argv[] = {const_cast<char*>(prog.c_str()), const_cast<char*>(arg.c_str()), nullptr};
  pid_t pid = 0;
  if (::posix_spawnp(&pid, prog.c_str(), nullptr, nullptr, argv, environ) != 0) return -1;
  int status = 0;
  if (::waitpid(pid, &status, 0) < 0) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f << text;
  f.close();
  if (!f) throw std::runtime_error(fmt::format("{}: cannot write", path.string()));
}

// The SVG at `svg`, with its data (.dat) and gnuplot script (.gp) next to it to redraw it.
void write_plot(const CalibrationComparison& c, const fs::path& svg, const std::string& title) {
  if (svg.has_parent_path()) fs::create_directories(svg.parent_path());
  fs::path data = svg, script = svg;
  data.replace_extension(".dat");
  script.replace_extension(".gp");
  write_text(data, comparison_plot_data(c));
  write_text(script, comparison_plot_script(c, data.string(), svg.string(), title));
  const int rc = run_gnuplot(script);
  if (rc != 0) {
    throw std::runtime_error(fmt::format("gnuplot {} failed ({}); the data and script are at {} and {}",
                                         script.string(), rc < 0 ? "not found" : fmt::format("exit {}", rc),
                                         data.string(), script.string()));
  }
}

// YYYY-MM-DD, optionally followed by THH:MM[:SS][Z]; the date must exist in the calendar.
std::string checked_date(const std::string& s) {
  static const std::regex re(R"((\d{4})-(\d{2})-(\d{2})(T(\d{2}):(\d{2})(:(\d{2}))?Z?)?)");
  std::smatch m;
  if (!std::regex_match(s, m, re)) {
    throw InputError(fmt::format("--date {}: expected an ISO 8601 date, YYYY-MM-DD or YYYY-MM-DDTHH:MM:SSZ", s));
  }
  const std::chrono::year_month_day ymd{std::chrono::year{std::stoi(m[1])},
                                        std::chrono::month{static_cast<unsigned>(std::stoi(m[2]))},
                                        std::chrono::day{static_cast<unsigned>(std::stoi(m[3]))}};
  if (!ymd.ok()) throw InputError(fmt::format("--date {}: no such day", s));
  if (m[4].matched && (std::stoi(m[5]) > 23 || std::stoi(m[6]) > 59 || (m[8].matched && std::stoi(m[8]) > 60))) {
    throw InputError(fmt::format("--date {}: no such time of day", s));
  }
  return s;
}

nlohmann::ordered_json drift_json(const DriftCheck& d, const CalibrationRecord& prev) {
  nlohmann::ordered_json j;
  j["previous_id"] = prev.id;
  j["previous_date"] = prev.date_utc;
  j["max_abs_arcsec"] = d.worst_arcsec;
  j["max_abs_offset_removed_arcsec"] = d.worst_shape_arcsec;
  j["axis"] = d.worst_axis;
  j["limit_arcsec"] = d.limit_arcsec;
  j["flagged"] = d.flagged;
  j["comparison"] = d.comparison.summary_json();
  return j;
}

void add_compare(CLI::App& app, Runner& run) {
  struct Opts {
    std::string a, b, plot, db, runs_dir = "runs";
    double range_deg = kDefaultCompareRangeDeg;
    bool json = false;
  };
  auto o = std::make_shared<Opts>();
  auto* sub = app.add_subcommand(
      "compare", "Difference B - A of two calibrations' transfer functions at equal counts, per axis (the paper's Figures 1-2)");
  sub->add_option("CAL_A", o->a, "coefficient file, published set (a-6-fpss1) or cal:ID from the catalogue")->required();
  sub->add_option("CAL_B", o->b, "the same for B")->required();
  sub->add_option("--range-deg", o->range_deg, "compare over the counts A maps into +-R deg")->capture_default_str();
  sub->add_flag("--json", o->json, "print {\"alpha\": {max_abs_arcsec, rms_arcsec, max_abs_offset_removed_arcsec}, \"beta\": {...}}");
  sub->add_option("--plot", o->plot, "write an SVG plot there (its .dat and .gp next to it)");
  sub->add_option("--db", o->db, "catalogue for cal:ID (default RUNS_DIR/stand.db)");
  sub->add_option("--runs-dir", o->runs_dir, "runs folder")->capture_default_str();
  sub->callback([o, &run] {
    run = [o] {
      const fs::path db = catalogue_path(o->db, o->runs_dir);
      const NamedSet a = resolve_calibration(o->a, db), b = resolve_calibration(o->b, db);
      const CalibrationComparison c = compare_calibrations(a.set, b.set, o->range_deg);
      if (!o->plot.empty()) {
        write_plot(c, o->plot, fmt::format("B - A: {} minus {}", b.name, a.name));
        std::fprintf(stderr, "plot: %s\n", o->plot.c_str());
      }
      if (o->json) {
        std::printf("%s\n", c.summary_json().dump().c_str());
      } else {
        std::printf("%s", comparison_table(c, a.name, b.name).c_str());
      }
      return 0;
    };
  });
}

void add_import(CLI::App& app, Runner& run) {
  struct Opts {
    std::string file, unit, date, label, db, runs_dir = "runs";
    double limit_arcsec = kDefaultDriftLimitArcsec;
    bool json = false;
  };
  auto o = std::make_shared<Opts>();
  auto* sub = app.add_subcommand("import", "Bring a calibration done elsewhere (a coefficient file) into the catalogue");
  sub->add_option("COEFFS", o->file, "coefficient file (JSON)")->required();
  sub->add_option("--unit", o->unit, "sensor unit serial")->required();
  sub->add_option("--date", o->date, "when the calibration was made (YYYY-MM-DD or ISO 8601 time)")->required();
  sub->add_option("--label", o->label, "a name for it (default: the file's \"calibration\" key, e.g. VI)");
  sub->add_option("--db", o->db, "catalogue file (default RUNS_DIR/stand.db)");
  sub->add_option("--runs-dir", o->runs_dir, "runs folder")->capture_default_str();
  sub->add_option("--limit-arcsec", o->limit_arcsec, "flag a change from the previous calibration beyond this")
      ->capture_default_str();
  sub->add_flag("--json", o->json, "print what was recorded as JSON");
  sub->callback([o, &run] {
    run = [o] {
      if (o->unit.empty()) throw InputError("--unit: the serial must not be empty");
      const std::string date = checked_date(o->date);
      std::ifstream in(o->file, std::ios::binary);
      if (!in) throw InputError(fmt::format("{}: cannot open", o->file));
      nlohmann::json j;
      try {
        j = nlohmann::json::parse(in);
      } catch (const nlohmann::json::parse_error& e) {
        throw InputError(fmt::format("{}: not JSON: {}", o->file, e.what()));
      }
      CalibrationRecord rec = CalibrationRecord::from_calibration_json(j, o->file);  // validates C1..C8
      if (!rec.unit.empty() && rec.unit != o->unit) {
        std::fprintf(stderr, "note: %s names unit \"%s\"; recorded against --unit %s\n", o->file.c_str(),
                     rec.unit.c_str(), o->unit.c_str());
      }
      rec.unit = o->unit;
      rec.source = "import";
      rec.run_id.reset();
      rec.source_ref = fs::absolute(o->file).lexically_normal().string();
      rec.date_utc = date;
      rec.method = "imported";
      rec.label = o->label;
      if (rec.label.empty() && j.contains("calibration") && j["calibration"].is_string()) {
        rec.label = j["calibration"].get<std::string>();
      }

      Catalogue cat(catalogue_path(o->db, o->runs_dir));
      // Importing the same file for the same date again is a no-op, so a script may repeat it.
      std::optional<int64_t> existing;
      for (const auto& h : cat.unit_history(o->unit)) {
        if (h.source == "import" && h.date_utc == date && h.coefficients == j) existing = h.id;
      }
      const int64_t id = existing ? *existing : cat.record_calibration(rec);

      // The change against the calibration just before it in the unit's history.
      const auto history = cat.unit_history(o->unit);
      std::optional<CalibrationRecord> prev;
      for (const auto& h : history) {
        if (h.id == id) break;
        prev = h;
      }
      std::optional<DriftCheck> drift;
      if (prev) {
        drift = check_drift(parse_coefficients(prev->coefficients, fmt::format("calibration {}", prev->id)),
                            parse_coefficients(j, o->file), o->limit_arcsec);
      }
      if (o->json) {
        nlohmann::ordered_json out;
        out["id"] = id;
        out["unit"] = o->unit;
        out["date"] = date;
        out["label"] = rec.label;
        out["already_present"] = existing.has_value();
        out["catalogue"] = cat.path().string();
        out["change"] = drift ? nlohmann::ordered_json(drift_json(*drift, *prev)) : nlohmann::ordered_json(nullptr);
        std::printf("%s\n", out.dump(1).c_str());
      } else {
        std::printf("%s calibration %lld of %s (%s%s) in %s\n", existing ? "already present as" : "imported as",
                    static_cast<long long>(id), o->unit.c_str(), date.c_str(),
                    rec.label.empty() ? "" : (", " + rec.label).c_str(), cat.path().c_str());
        if (drift) {
          std::printf("change from calibration %lld (%s): max %.2f arcsec (%s), %.2f arcsec with the null shift removed%s\n",
                      static_cast<long long>(prev->id), prev->date_utc.c_str(), drift->worst_arcsec,
                      drift->worst_axis.c_str(), drift->worst_shape_arcsec,
                      drift->flagged ? fmt::format("  ** beyond {} arcsec **", drift->limit_arcsec).c_str() : "");
        }
      }
      return 0;
    };
  });
}

void add_accept_command(CLI::App& app, Runner& run) {
  auto* sub = app.add_subcommand("accept", "(not implemented yet: issue 6, acceptance)");
  sub->allow_extras();
  sub->callback([&run] {
    run = [] {
      std::fprintf(stderr, "fpss-stand accept: not implemented yet (issue 6)\n");
      return 1;
    };
  });
}

}  // namespace

void add_accept(CLI::App& app, Runner& run) {
  add_accept_command(app, run);
  add_compare(app, run);
  add_import(app, run);
}

}  // namespace fpss::cli
