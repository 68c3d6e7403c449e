#include "stand/report/run_summary.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <fstream>

#include "base/errors.h"
#include "base/json_file.h"
#include "stand/report/report.h"

namespace fpss {

namespace fs = std::filesystem;

namespace {

std::string stats_text(const std::optional<AxisResidualStats>& s) {
  if (!s || !s->mean_abs_arcsec) return "-";
  std::string t = fmt::format("mean |r| {:.3f}", *s->mean_abs_arcsec);
  if (s->sd_arcsec) t += fmt::format(" +- {:.3f}", *s->sd_arcsec);
  if (s->max_abs_arcsec) t += fmt::format(", max {:.3f}", *s->max_abs_arcsec);
  if (s->rms_arcsec) t += fmt::format(", rms {:.3f}", *s->rms_arcsec);
  t += " arcsec";
  if (s->points) t += fmt::format(", {} points", *s->points);
  if (s->range_lo_deg && s->range_hi_deg) t += fmt::format(", range {:+.2f}..{:+.2f} deg", *s->range_lo_deg, *s->range_hi_deg);
  return t;
}

// GAP.json's verdict and causes; nullopt for a folder without one, or a diagnosis of several units
// (no verdict of its own: each unit's GAP.json has it).
std::optional<RunSummary::Diagnosis> read_diagnosis(const fs::path& run_dir, const RunFile& run) {
  std::string name = "GAP.json";
  if (run.files.gap && !run.files.gap->empty() && fs::path(*run.files.gap).filename() == *run.files.gap) name = *run.files.gap;
  if (!fs::is_regular_file(run_dir / name)) return std::nullopt;
  const nlohmann::json g = read_json_file(run_dir / name, "diagnosis (GAP.json)");
  if (!g.is_object() || !g.contains("verdict") || !g["verdict"].is_string()) return std::nullopt;
  RunSummary::Diagnosis d;
  d.file = name;
  d.verdict = g["verdict"].get<std::string>();
  if (g.contains("verdict_sentence") && g["verdict_sentence"].is_string()) d.sentence = g["verdict_sentence"].get<std::string>();
  if (g.contains("cause") && g["cause"].is_string()) d.cause = g["cause"].get<std::string>();
  if (g.contains("causes") && g["causes"].is_array()) {
    for (const auto& c : g["causes"]) {
      if (c.is_object() && c.contains("name") && c["name"].is_string()) d.causes.push_back(c["name"].get<std::string>());
    }
  }
  return d;
}

std::string diagnosis_text(const RunSummary::Diagnosis& d) {
  std::string verdict = d.verdict;
  std::transform(verdict.begin(), verdict.end(), verdict.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  std::string t = fmt::format("  diagnosis  {}{}\n", verdict, d.sentence.empty() ? "" : ": " + d.sentence);
  std::string causes = d.cause.empty() || d.cause == "none" ? "none" : d.cause;
  for (size_t k = 1; k < d.causes.size(); ++k) causes += ", then " + d.causes[k];
  t += fmt::format("             cause {} ({})\n", causes, d.file);
  return t;
}

}  // namespace

namespace {

// The verdict of one unit's run: its acceptance, else how the run ended.
RunVerdict single_run_verdict(const RunFile& run) {
  const std::string& outcome = run.outcome;
  const std::string cause = run.stop_cause ? to_string(*run.stop_cause) : "";
  const std::string reason = run.reason.value_or("");
  if (run.acceptance) {
    const auto& acc = *run.acceptance;
    if (acc.verdict == "pass") return {"pass", "acceptance passed: every criterion within its limit"};
    std::string failed;
    for (const auto& f : acc.failed.value_or(std::vector<std::string>{})) failed += (failed.empty() ? "" : ", ") + f;
    // Conditional: nothing failed, but a value lies within its guard band (acceptance.json says which).
    if (acc.verdict == "conditional") {
      return {"conditional", "acceptance conditional: no criterion beyond its limit, but one or more within the guard "
                             "band of the decision rule (the certificate says which and why)"};
    }
    return {"fail", failed.empty() ? "acceptance failed" : "acceptance failed: " + failed};
  }
  if (outcome == "running") return {"running", "the run is in progress"};
  if (outcome == "completed") return {"pass", "the run completed and every check step held"};
  if (outcome == "failed" && (cause == "check_failed" || cause == "calibration_failed")) {
    return {"fail", reason.empty() ? cause : reason};
  }
  return {"incomplete", fmt::format("the run {}{} before a verdict{}", outcome, cause.empty() ? "" : " (" + cause + ")",
                                    reason.empty() ? "" : ": " + reason)};
}

// Several units: every unit passes, or the worst of their verdicts with each unit's reason.
RunVerdict units_verdict(const RunFile& run) {
  static const std::vector<std::string> worst_first = {"fail", "incomplete", "conditional", "running", "pass"};
  size_t worst = worst_first.size() - 1, passed = 0;
  std::string why;
  for (const RunFileUnit& u : *run.units) {
    const RunVerdict v = unit_verdict(run, u);
    const size_t rank = static_cast<size_t>(std::find(worst_first.begin(), worst_first.end(), v.verdict) - worst_first.begin());
    worst = std::min(worst, rank);
    if (v.verdict == "pass") ++passed;
    else why += fmt::format("{}unit {}: {}", why.empty() ? "" : "; ", u.serial, v.why);
  }
  if (worst == worst_first.size() - 1) return {"pass", fmt::format("every unit ({}) passed", passed)};
  return {worst_first[std::min(worst, worst_first.size() - 1)],
          fmt::format("{} of {} units pass; {}", passed, run.units->size(), why)};
}

}  // namespace

RunVerdict run_verdict(const RunFile& run) {
  if (run.units && !run.units->empty()) return units_verdict(run);
  return single_run_verdict(run);
}

RunVerdict unit_verdict(const RunFile& run, const RunFileUnit& u) {
  if (u.outcome == "lost") {
    return {"fail", fmt::format("unit {} lost ({}){}: {}", u.serial, u.loss_cause.value_or("?"),
                                u.lost_at_point && *u.lost_at_point > 0 ? fmt::format(" at point {}", *u.lost_at_point)
                                                                        : std::string(" before the first point"),
                                u.reason.value_or(""))};
  }
  if (u.verdict) {
    if (*u.verdict == "pass") return {"pass", "acceptance passed: every criterion within its limit"};
    if (*u.verdict == "conditional") {
      return {"conditional", "acceptance conditional: a value within the guard band (see its certificate)"};
    }
    return {"fail", "acceptance failed (see its certificate)"};
  }
  return single_run_verdict(run);
}

RunVerdict run_verdict(const std::optional<RunFile>& run) {
  if (!run) return {"incomplete", "run.json does not say how the run ended"};
  return run_verdict(*run);
}

std::string verdict_banner_html(const RunVerdict& v, const std::string& id) {
  const char* colour = v.verdict == "pass" ? "#1e7d32" : v.verdict == "fail" ? "#c0392b" : "#8a6d00";
  std::string word = v.verdict;
  std::transform(word.begin(), word.end(), word.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  return fmt::format(
      "<div id=\"{4}\" class=\"verdict {0}\" style=\"background:{1};color:#fff;padding:0.6em 1em;margin:0.8em 0;"
      "border-radius:4px\"><strong style=\"font-size:1.6em\">{2}</strong> <span>{3}</span></div>\n",
      html_escape(v.verdict), colour, html_escape(word), html_escape(v.why), html_escape(id));
}

std::optional<int64_t> fit_last_step(const CoefficientSet& cal, const std::string& origin) {
  if (!cal.extra.is_object() || !cal.extra.contains("fit_last_step")) return std::nullopt;
  const auto& v = cal.extra["fit_last_step"];
  if (!v.is_number_integer() || v.get<int64_t>() < 0) {
    throw InputError(fmt::format("{}: \"fit_last_step\" must be a whole number >= 0", origin));
  }
  return v.get<int64_t>();
}

int64_t journal_points(const fs::path& run_dir) {
  const fs::path p = run_dir / "points.jsonl";
  std::error_code ec;
  if (!fs::is_regular_file(p, ec)) return 0;
  std::ifstream in(p, std::ios::binary);
  int64_t lines = 0;
  char buf[65536];
  while (in.read(buf, sizeof buf) || in.gcount() > 0) {
    lines += std::count(buf, buf + in.gcount(), '\n');
  }
  return lines;
}

RunSummary read_run_summary(const fs::path& run_dir) {
  const fs::path run_json = run_dir / "run.json";
  if (!fs::is_directory(run_dir)) throw InputError(fmt::format("{}: not a run folder (no such folder)", run_dir.string()));
  if (!fs::exists(run_json)) throw InputError(fmt::format("{}: missing: not a run folder", run_json.string()));
  const RunFile run = read_run_file(run_dir);
  RunSummary s;
  s.dir = run_dir;
  s.run_id = run.id_or(run_dir);
  s.unit = run.unit;
  s.procedure = run.procedure.name;
  s.outcome = run.outcome;
  s.stop_cause = run.stop_cause ? to_string(*run.stop_cause) : "";
  s.reason = run.reason.value_or("");
  s.started_utc = run.started_utc;
  s.ended_utc = run.ended_utc.value_or("");
  s.emulated = run.emulated;
  s.points_total = run.points.total;
  s.points_done = journal_points(run_dir);
  s.verdict = run_verdict(run);
  std::string cal = "calibration.json";
  if (run.files.calibration) {
    const std::string& named = *run.files.calibration;
    if (!named.empty() && fs::path(named).filename() == named) cal = named;
  }
  if (fs::is_regular_file(run_dir / cal)) {
    s.calibration = cal;
    const nlohmann::json c = read_json_file(run_dir / cal, "calibration file");
    if (c.is_object() && c.contains("residuals") && c["residuals"].is_object()) {
      const std::string where = (run_dir / cal).string() + " residuals";
      if (c["residuals"].contains("pitch")) s.pitch = AxisResidualStats::from_json(c["residuals"]["pitch"], where);
      if (c["residuals"].contains("yaw")) s.yaw = AxisResidualStats::from_json(c["residuals"]["yaw"], where);
    }
  }
  for (const auto& e : fs::directory_iterator(run_dir)) {
    const std::string name = e.path().filename().string();
    if (!name.empty() && name[0] != '.') s.files.push_back(name);
  }
  std::sort(s.files.begin(), s.files.end());
  s.diagnosis = read_diagnosis(run_dir, run);
  if (run.units) {
    for (const RunFileUnit& u : *run.units) s.units.push_back({u, unit_verdict(run, u)});
  }
  return s;
}

nlohmann::ordered_json RunSummary::to_json() const {
  auto opt = [](const std::string& v) { return v.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(v); };
  auto axis = [](const std::optional<AxisResidualStats>& a) {
    return a ? nlohmann::ordered_json(a->to_json()) : nlohmann::ordered_json(nullptr);
  };
  nlohmann::ordered_json j;
  j["run_id"] = run_id;
  j["run_dir"] = fs::absolute(dir).lexically_normal().string();
  j["unit"] = unit;
  j["procedure"] = procedure;
  j["emulated"] = emulated;
  j["started_utc"] = opt(started_utc);
  j["ended_utc"] = opt(ended_utc);
  j["outcome"] = outcome;
  j["stop_cause"] = opt(stop_cause);
  j["reason"] = opt(reason);
  j["verdict"] = verdict.verdict;
  j["verdict_reason"] = verdict.why;
  j["points"] = {{"done", points_done}, {"total", points_total}};
  j["calibration"] = opt(calibration);
  j["residuals"] = {{"pitch", axis(pitch)}, {"yaw", axis(yaw)}};
  j["files"] = files;
  if (diagnosis) {
    j["diagnosis"] = {{"file", diagnosis->file},     {"verdict", diagnosis->verdict},
                      {"verdict_sentence", diagnosis->sentence}, {"cause", diagnosis->cause},
                      {"causes", diagnosis->causes}};
  } else {
    j["diagnosis"] = nullptr;
  }
  if (!units.empty()) {
    j["units"] = nlohmann::ordered_json::array();
    for (const Unit& u : units) {
      nlohmann::ordered_json e = nlohmann::ordered_json::parse(fpss::to_json(u.unit).dump());
      e["verdict"] = u.verdict.verdict;
      e["verdict_reason"] = u.verdict.why;
      j["units"].push_back(e);
    }
  }
  return j;
}

std::string RunSummary::text() const {
  std::string verdict_word = verdict.verdict;
  std::transform(verdict_word.begin(), verdict_word.end(), verdict_word.begin(),
                 [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  std::string t = fmt::format("run {}\n", run_id);
  t += fmt::format("  folder     {}\n", fs::absolute(dir).lexically_normal().string());
  t += fmt::format("  unit       {}   procedure {}   bench {}\n", unit.empty() ? "-" : unit,
                   procedure.empty() ? "-" : procedure, emulated ? "emulated" : "stand");
  t += fmt::format("  started    {}   ended {}\n", started_utc.empty() ? "-" : started_utc,
                   ended_utc.empty() ? "-" : ended_utc);
  t += fmt::format("  outcome    {}{}{}\n", outcome.empty() ? "-" : outcome,
                   stop_cause.empty() || stop_cause == "none" ? "" : " (" + stop_cause + ")",
                   reason.empty() ? "" : ": " + reason);
  t += fmt::format("  verdict    {}: {}\n", verdict_word, verdict.why);
  if (diagnosis) t += diagnosis_text(*diagnosis);
  t += fmt::format("  points     {}/{}\n", points_done, points_total);
  t += fmt::format("  residuals  pitch {}\n             yaw   {}\n", stats_text(pitch), stats_text(yaw));
  t += fmt::format("  calibration {}\n", calibration.empty() ? "none" : calibration);
  t += fmt::format("  files      {}\n", fmt::join(files, " "));
  for (size_t i = 0; i < units.size(); ++i) {
    const RunFileUnit& u = units[i].unit;
    std::string word = units[i].verdict.verdict;
    std::transform(word.begin(), word.end(), word.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
    t += fmt::format("  {} {}  {}  {}  {}\n", i == 0 ? "units     " : "          ", u.serial,
                     u.outcome + (u.loss_cause ? " (" + *u.loss_cause + ")" : ""), word, u.calibration.value_or("no calibration"));
    if (u.relative) {
      const RunFileRelative& r = *u.relative;
      t += fmt::format("             relative to {}: boresight pitch {:+.3f} +- {:.3f}, yaw {:+.3f} +- {:.3f}, "
                       "roll {:+.2f} +- {:.2f} arcsec\n",
                       r.to, r.boresight_pitch_arcsec, r.boresight_pitch_sigma_arcsec, r.boresight_yaw_arcsec,
                       r.boresight_yaw_sigma_arcsec, r.roll_arcsec, r.roll_sigma_arcsec);
    }
  }
  return t;
}

}  // namespace fpss
