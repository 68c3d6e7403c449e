// fpss-stand compare / import: the difference of two calibrations (the paper's Figures 1-2), and calibrations done elsewhere brought into the catalogue.
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/clock.h"
#include "base/errors.h"
#include "base/json_file.h"
#include "base/text_file.h"
#include "calib/coefficients.h"
#include "calib/compare.h"
#include "fixtures/bench.h"
#include "procedures/plan.h"
#include "procedures/recorder.h"
#include "stand/acceptance/acceptance.h"
#include "stand/catalogue/run_file.h"
#include "stand/catalogue/catalogue.h"
#include "stand/cli/catalogue_option.h"
#include "stand/cli/commands.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"
#include "stand/cli/emulated_bench.h"
#include "stand/config/stand_config.h"
#include "stand/report/compare_plot.h"
#include "stand/report/report.h"
#include "stand/report/units_page.h"
#include "stand/session/session.h"

namespace fpss::cli {
namespace fs = std::filesystem;
namespace {

// A calibration named on the command line: a coefficient file (calibration.json is one), a
// published set ("a-6-fpss1"), or "cal:ID" for a calibration in the catalogue.
struct NamedSet {
  CoefficientSet set;
  std::string name;
};

NamedSet resolve_calibration(const std::string& arg, const std::string& url) {
  if (arg.rfind("cal:", 0) == 0) {
    int64_t id = 0;
    try {
      size_t used = 0;
      id = std::stoll(arg.substr(4), &used);
      if (used != arg.size() - 4) throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
      throw InputError(fmt::format("{}: expected cal:ID with a numeric catalogue id", arg));
    }
    const auto cat = open_catalogue(url, Catalogue::Mode::read_only);
    const std::string where = cat->location();
    const auto rec = cat->find_calibration(id);
    if (!rec) throw InputError(fmt::format("{}: no calibration {} in {}", arg, id, where));
    NamedSet n{parse_coefficients(rec->coefficients, fmt::format("{} calibration {}", where, id)), {}};
    n.name = fmt::format("{} calibration {} of {} ({}{})", where, id, rec->unit, rec->date_utc,
                         rec->label.empty() ? "" : ", " + rec->label);
    return n;
  }
  if (fs::exists(arg)) return {load_coefficients(arg), arg};
  for (const auto& name : published_names()) {
    if (name == arg) return {load_published(name), fmt::format("published {}", name)};
  }
  // A published set's name mistyped (a-6-fpss, a6-fpss1): the closest one.
  const std::string near = arg.find('/') == std::string::npos ? closest(arg, published_names()) : std::string();
  throw InputError(fmt::format("{}: no such coefficient file, published set (a-1-fpss1 .. a-7-fpss2) or cal:ID{}", arg,
                               near.empty() ? "" : "; did you mean " + near + "?"));
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
  return {{"previous_id", prev.id}, {"previous_date", prev.date_utc},
          {"max_abs_arcsec", d.worst_arcsec}, {"max_abs_offset_removed_arcsec", d.worst_shape_arcsec},
          {"axis", d.worst_axis}, {"limit_arcsec", d.limit_arcsec}, {"flagged", d.flagged},
          {"comparison", d.comparison.summary_json()}};
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
  expect_file(sub, sub->add_option("CAL_A", o->a, "coefficient file, published set (a-6-fpss1) or cal:ID from the catalogue")->required(),
              o->a, FileKind::coefficients);
  expect_file(sub, sub->add_option("CAL_B", o->b, "the same for B")->required(), o->b, FileKind::coefficients);
  sub->add_option("--range-deg", o->range_deg, "compare over the counts A maps into +-R deg")->capture_default_str();
  sub->add_flag("--json", o->json, "print {\"alpha\": {max_abs_arcsec, rms_arcsec, max_abs_offset_removed_arcsec}, \"beta\": {...}}");
  sub->add_option("--plot", o->plot, "write an SVG plot there (its .dat and .gp next to it)");
  add_catalogue_option(sub, o->db);
  sub->add_option("--runs-dir", o->runs_dir, "runs folder")->capture_default_str();
  examples(sub, {"fpss-stand compare a-5-fpss1 a-6-fpss1",
                 "fpss-stand compare calib/data/published/a-4-fpss2.json a-5-fpss2 --range-deg 0.3 --json"});
  sub->callback([o, &run] {
    run = [o] {
      const std::string db = catalogue_url(o->db, o->runs_dir);
      if (!o->plot.empty()) {
        // The plot's folder is made when missing; then the one output check (folder writable, no input overwritten).
        const fs::path svg = o->plot;
        std::error_code ec;
        if (svg.has_parent_path()) fs::create_directories(svg.parent_path(), ec);
        if (ec) throw InputError(fmt::format("--plot {}: cannot make its folder: {}", o->plot, ec.message()));
        fs::path data = svg, script = svg;
        data.replace_extension(".dat");
        script.replace_extension(".gp");
        for (const fs::path& p : {svg, data, script}) check_output_path(p, {o->a, o->b, sqlite_file_of(db)}, "--plot");
      }
      const NamedSet a = resolve_calibration(o->a, db), b = resolve_calibration(o->b, db);
      const CalibrationComparison c = compare_calibrations(a.set, b.set, o->range_deg);
      if (!o->plot.empty()) {
        write_comparison_plot(c, o->plot, fmt::format("B - A: {} minus {}", b.name, a.name));
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
  expect_file(sub, sub->add_option("COEFFS", o->file, "coefficient file (JSON)")->required(), o->file,
              FileKind::coefficients);
  sub->add_option("--unit", o->unit, "sensor unit serial")->required();
  sub->add_option("--date", o->date, "when the calibration was made (YYYY-MM-DD or ISO 8601 time)")->required();
  sub->add_option("--label", o->label, "a name for it (default: the file's \"calibration\" key, e.g. VI)");
  add_catalogue_option(sub, o->db);
  sub->add_option("--runs-dir", o->runs_dir, "runs folder")->capture_default_str();
  sub->add_option("--limit-arcsec", o->limit_arcsec, "flag a change from the previous calibration beyond this")
      ->capture_default_str();
  sub->add_flag("--json", o->json, "print what was recorded as JSON");
  examples(sub, {"fpss-stand import calib/data/published/a-6-fpss1.json --unit FPSS1 --date 1980-08-27 --runs-dir runs",
                 "fpss-stand history FPSS1 --runs-dir runs"});
  sub->callback([o, &run] {
    run = [o] {
      if (o->unit.empty()) throw InputError("--unit: the serial must not be empty");
      const std::string date = checked_date(o->date);
      const std::string url = catalogue_url(o->db, o->runs_dir);
      const fs::path db_path = sqlite_file_of(url);
      if (!db_path.empty() && fs::exists(db_path)) check_output_path(db_path, {o->file}, "--db");
      const nlohmann::json j = read_json_file(o->file, "coefficient file");
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

      const auto catp = open_catalogue(url);
      Catalogue& cat = *catp;
      // Importing the same file for the same date again is a no-op, so a script may repeat it;
      // check and insert are one transaction, so two imports at once record it once.
      const auto [id, inserted] = cat.record_import_once(rec);
      const std::optional<int64_t> existing = inserted ? std::nullopt : std::optional<int64_t>(id);

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
        out["catalogue"] = cat.location();
        out["change"] = drift ? nlohmann::ordered_json(drift_json(*drift, *prev)) : nlohmann::ordered_json(nullptr);
        std::printf("%s\n", out.dump(1).c_str());
      } else {
        std::printf("%s calibration %lld of %s (%s%s) in %s\n", existing ? "already present as" : "imported as",
                    static_cast<long long>(id), o->unit.c_str(), date.c_str(),
                    rec.label.empty() ? "" : (", " + rec.label).c_str(), cat.location().c_str());
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

}  // namespace

void add_compare_import(CLI::App& app, Runner& run) {
  add_compare(app, run);
  add_import(app, run);
}

}  // namespace fpss::cli
