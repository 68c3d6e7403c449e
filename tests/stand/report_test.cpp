// report.html from a real run folder (samples.csv, calibration.json, run.json) with real gnuplot.
#include "stand/report/report.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <regex>
#include <set>

#include "base/errors.h"
#include "calib/calibrator.h"
#include "calib/coefficients.h"
#include "calib/samples.h"
#include "calib/units.h"
#include "stand/report/plot.h"
#include "tests/support/test_support.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;

using test::read_file;
using test::TempDir;

size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t i = text.find(what); i != std::string::npos; i = text.find(what, i + 1)) ++n;
  return n;
}

// The paper's null -> offset -> null pattern along pitch, then yaw: +-0.42 deg in 0.06 deg steps.
struct Offset {
  double pitch_arcsec, yaw_arcsec;
};
std::vector<Offset> grid() {
  std::vector<Offset> g;
  for (int axis = 0; axis < 2; ++axis) {
    for (int k = -7; k <= 7; ++k) {
      if (k == 0) continue;
      const double a = deg_to_arcsec(0.06 * k);
      g.push_back(axis == 0 ? Offset{a, 0} : Offset{0, a});
    }
  }
  return g;
}

// Writes a recording of `truth` with the stand's writer: `per_dwell` samples per dwell, sensor
// noise in counts (0: exact fractional counts), rounded to integers when noisy.
void write_recording(const fs::path& path, const CoefficientSet& truth, double noise_counts, uint32_t seed,
                     int per_dwell = 4) {
  SamplesCsvWriter w(path, {"temperature_c", "frame_seq"});
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_counts > 0 ? noise_counts : 1.0);
  const AxisModel am = truth.alpha_model(), bm = truth.beta_model();
  double t = 0;
  int64_t step = 0;
  int seq = 0;
  auto dwell = [&](Phase phase, double pitch, double yaw) {
    ++step;
    const double na = am.counts_for_angle(arcsec_to_rad(pitch));
    const double nb = bm.counts_for_angle(arcsec_to_rad(yaw));
    for (int i = 0; i < per_dwell; ++i) {
      Sample s;
      s.time_s = t;
      t += 0.25;
      s.phase = phase;
      s.step = step;
      s.ref_pitch_arcsec = pitch;
      s.ref_yaw_arcsec = yaw;
      s.counts_alpha = noise_counts > 0 ? std::round(na + noise(rng)) : na;
      s.counts_beta = noise_counts > 0 ? std::round(nb + noise(rng)) : nb;
      w.append(s, {"21.5", std::to_string(seq++)});
    }
    t += 2.0;
  };
  for (const auto& o : grid()) {
    dwell(Phase::null, 0, 0);
    dwell(Phase::offset, o.pitch_arcsec, o.yaw_arcsec);
  }
  dwell(Phase::null, 0, 0);
  w.sync();
}

CoefficientSet truth() { return load_published("a-6-fpss1"); }

// The truth with small known changes: the calibration the report judges.
CoefficientSet perturbed() {
  CoefficientSet c = truth();
  c.alpha[2] += 1.0e-6;  // C3: +0.206 arcsec on the first sinusoid of pitch
  c.beta[5] += 1.5e-6;   // C6: +0.309 arcsec on the second sinusoid of yaw
  c.extra = nlohmann::json::object();
  c.extra["method"] = "differences";
  return c;
}

// run.json as the engine writes it (stand/session/session.cpp), in part.
nlohmann::json run_json() {
  return {{"format", "fpss-stand run/1"},
          {"run_id", "20240501T120000Z-FPSS1-discrete_grid"},
          {"unit", "FPSS1"},
          {"procedure",
           {{"name", "discrete_grid"},
            {"sha256", "3f2a"},
            {"text", "name: discrete_grid\nsteps:\n  - home: {}\n  - null_offset_grid: {extent_deg: 0.42}\n"}}},
          {"emulated", true},
          {"emulator", {{"seed", 7}}},
          {"started_utc", "2024-05-01T12:00:00Z"},
          {"outcome", "completed"},
          {"points", {{"total", 113}, {"completed", 113}}},
          {"sessions", {{{"session", 1}, {"pid", 123}}}},
          {"files", {{"samples", "samples.csv"}, {"calibration", "calibration.json"}}},
          {"note", "<b>operator</b> & co"}};
}

void make_run_folder(const fs::path& dir) {
  fs::remove_all(dir);  // the samples writer appends to an existing file
  fs::create_directories(dir);
  write_recording(dir / "samples.csv", truth(), 0.0, 1);
  save_coefficients(dir / "calibration.json", perturbed());
  std::ofstream(dir / "run.json") << run_json().dump(1);
}

struct Expected {
  double mean, sd, max;
  size_t points;
};

// Residuals of the perturbed set computed straight from the grid (no file, no dwell code): for
// every offset, the model's change minus the reference change, there and back.
Expected expected_residuals(bool pitch) {
  const CoefficientSet t = truth(), c = perturbed();
  const AxisModel truth_model = pitch ? t.alpha_model() : t.beta_model();
  const AxisModel cal_model = pitch ? c.alpha_model() : c.beta_model();
  const double n0 = truth_model.counts_for_angle(0.0);
  std::vector<double> r;
  for (const auto& o : grid()) {
    const double ref = pitch ? o.pitch_arcsec : o.yaw_arcsec;
    const double n = truth_model.counts_for_angle(arcsec_to_rad(ref));
    const double change = cal_model.angle_arcsec(n) - cal_model.angle_arcsec(n0);
    r.push_back(change - ref);  // against the null before
    r.push_back(change - ref);  // and the null after (the same here: the nulls are exact)
  }
  Expected e{0, 0, 0, r.size()};
  for (double v : r) { e.mean += std::abs(v); e.max = std::max(e.max, std::abs(v)); }
  e.mean /= static_cast<double>(r.size());
  for (double v : r) e.sd += (std::abs(v) - e.mean) * (std::abs(v) - e.mean);
  e.sd = std::sqrt(e.sd / static_cast<double>(r.size() - 1));
  return e;
}

TEST(Report, ResidualsAreTheCalibrationsOnTheRecording) {
  TempDir dir;
  make_run_folder(dir.path());
  const auto samples = read_samples_csv(dir.path() / "samples.csv");
  const auto r = compute_residuals(samples, perturbed(), "differences");
  EXPECT_EQ(r.offset_dwells, grid().size());
  EXPECT_EQ(r.null_dwells, grid().size() + 1);
  ASSERT_EQ(r.points.size(), 2 * grid().size());
  for (const auto& [st, pitch] : {std::pair{&r.pitch, true}, std::pair{&r.yaw, false}}) {
    const Expected e = expected_residuals(pitch);
    EXPECT_GT(e.max, 0.05);  // the perturbation is visible, so the figures mean something
    EXPECT_EQ(st->points.value(), static_cast<int64_t>(e.points));
    EXPECT_NEAR(st->mean_abs_arcsec.value(), e.mean, 1e-6);
    EXPECT_NEAR(st->sd_arcsec.value(), e.sd, 1e-6);
    EXPECT_NEAR(st->max_abs_arcsec.value(), e.max, 1e-6);
    EXPECT_NEAR(st->range_lo_deg.value(), -0.42, 1e-9);
    EXPECT_NEAR(st->range_hi_deg.value(), 0.42, 1e-9);
  }
  // Offsets along yaw move no pitch counts: their pitch residuals vanish.
  for (const auto& p : r.points) {
    if (p.ref_pitch_arcsec == 0) {
      EXPECT_NEAR(p.pitch_arcsec, 0.0, 1e-9) << "step " << p.step;
    }
  }
  EXPECT_THROW(compute_residuals(samples, perturbed(), "sideways"), InputError);
}

// On a noisy recording fitted by the calibrator, the report's figures are the calibrator's own.
TEST(Report, FiguresEqualTheCalibratorsResidualsBlock) {
  TempDir dir;
  write_recording(dir.path() / "samples.csv", truth(), 0.3, 42);
  const auto samples = read_samples_csv(dir.path() / "samples.csv");
  CalibrationOptions opts;
  opts.unit = "FPSS1";
  const CalibrationReport rep = calibrate(samples, opts);
  save_coefficients(dir.path() / "calibration.json", rep.coefficients());

  const ReportInput in = load_report_input(dir.path());
  for (const auto& [mine, theirs] : {std::pair{&in.residuals.pitch, &rep.pitch.residuals},
                                     std::pair{&in.residuals.yaw, &rep.yaw.residuals}}) {
    EXPECT_EQ(mine->points.value(), static_cast<int64_t>(theirs->points));
    EXPECT_NEAR(mine->mean_abs_arcsec.value(), theirs->mean_abs_arcsec, 1e-9);
    EXPECT_NEAR(mine->sd_arcsec.value(), theirs->sd_arcsec, 1e-9);
    EXPECT_NEAR(mine->max_abs_arcsec.value(), theirs->max_abs_arcsec, 1e-9);
    EXPECT_NEAR(mine->range_lo_deg.value(), theirs->range_deg[0], 1e-12);
    EXPECT_NEAR(mine->range_hi_deg.value(), theirs->range_deg[1], 1e-12);
  }
  const std::string html = render_report(in, {});
  EXPECT_EQ(html.find("differs from the residuals"), std::string::npos) << "calibration.json agrees";
  EXPECT_NE(html.find("No run.json in this folder"), std::string::npos);
  EXPECT_NE(html.find(fmt::format("{:.2f} &plusmn; {:.2f}", rep.pitch.residuals.mean_abs_arcsec,
                                  rep.pitch.residuals.sd_arcsec)),
            std::string::npos);
}

TEST(Report, TheUncertaintyBudgetIsCalibrationJsons) {
  TempDir dir;
  write_recording(dir.path() / "samples.csv", truth(), 0.3, 42);
  const CalibrationReport rep = calibrate(read_samples_csv(dir.path() / "samples.csv"), {});
  save_coefficients(dir.path() / "calibration.json", rep.coefficients());
  const std::string html = render_report(load_report_input(dir.path()), {});
  ASSERT_NE(html.find("<section id=\"budget\">"), std::string::npos);
  const nlohmann::json u = rep.coefficients().extra.at("uncertainties");
  for (const char* axis : {"pitch", "yaw"}) {
    const auto& a = u.at(axis);
    EXPECT_NE(html.find(fmt::format("expanded U (k = {:.3f}, 95 %)</th><td></td><td>{:.4f}", a.at("coverage_factor").get<double>(),
                                    a.at("expanded_uncertainty_max_arcsec").get<double>())),
              std::string::npos)
        << axis;
    for (const auto& e : a.at("budget")) {
      EXPECT_NE(html.find(fmt::format("<td class=\"l\">{}</td><td>{}</td><td>{:.4f}</td>", e.at("source").get<std::string>(),
                                      e.at("type").get<std::string>(), e.at("u_arcsec").get<double>())),
                std::string::npos)
          << e.dump();
    }
  }
}

TEST(Report, PageHasTheSummaryAndInlineSvgPlots) {
  TempDir dir;
  const fs::path run = dir.path() / "20240501T120000Z-FPSS1-discrete_grid";
  make_run_folder(run);
  const fs::path out = write_report(run);
  EXPECT_EQ(out, run / "report.html");
  EXPECT_FALSE(fs::exists(run / "report.html.tmp"));
  const std::string html = read_file(out);

  // The Table 1 figures, as computed independently.
  for (bool pitch : {true, false}) {
    const Expected e = expected_residuals(pitch);
    EXPECT_NE(html.find(fmt::format("{:.2f} &plusmn; {:.2f}</td><td>{:.2f}</td>", e.mean, e.sd, e.max)),
              std::string::npos)
        << (pitch ? "pitch" : "yaw");
  }
  EXPECT_NE(html.find("-0.42 to +0.42"), std::string::npos);
  EXPECT_NE(html.find("<td>56</td>"), std::string::npos);  // points per axis: 28 offsets, there and back
  EXPECT_NE(html.find("unit FPSS1"), std::string::npos);

  // Three plots drawn by gnuplot, inline: pitch and yaw against angle, and the map.
  EXPECT_EQ(count(html, "<svg"), 3u);
  EXPECT_EQ(count(html, "</svg>"), 3u);
  EXPECT_NE(html.find("Pitch residuals against pitch angle"), std::string::npos);
  EXPECT_NE(html.find("Yaw residuals against yaw angle"), std::string::npos);
  EXPECT_NE(html.find("Residual map over the field"), std::string::npos);
  EXPECT_EQ(count(html, "class=\"missing\""), 0u);
  // Readable offline: nothing fetched, nothing run.
  EXPECT_EQ(count(html, "<script"), 0u);
  EXPECT_EQ(count(html, "<?xml"), 0u);
  EXPECT_FALSE(std::regex_search(html, std::regex(R"((src|href)\s*=\s*["']?(https?:|//|file:))")));
  // Every id on the page once, and every reference points at one of them.
  std::set<std::string> ids;
  const std::regex id_re(R"re(\sid=['"]([^'"]+)['"])re");
  for (auto it = std::sregex_iterator(html.begin(), html.end(), id_re); it != std::sregex_iterator(); ++it) {
    EXPECT_TRUE(ids.insert((*it)[1]).second) << "duplicate id " << (*it)[1];
  }
  const std::regex ref_re(R"re((?:href=['"]#|url\(#)([^'")]+))re");
  for (auto it = std::sregex_iterator(html.begin(), html.end(), ref_re); it != std::sregex_iterator(); ++it) {
    EXPECT_TRUE(ids.count((*it)[1])) << "dangling reference #" << (*it)[1];
  }
  // run.json's fields are shown, escaped; the procedure text folded away.
  EXPECT_NE(html.find("&lt;b&gt;operator&lt;/b&gt; &amp; co"), std::string::npos);
  EXPECT_EQ(html.find("<b>operator</b>"), std::string::npos);
  EXPECT_NE(html.find("<summary><code>procedure.text</code></summary><pre>name: discrete_grid\nsteps:"),
            std::string::npos);
  EXPECT_NE(html.find("<th class=\"l\">emulator.seed</th><td class=\"l\">7</td>"), std::string::npos);
  EXPECT_NE(html.find(", discrete_grid</title>"), std::string::npos);
  EXPECT_NE(html.find("<td class=\"l\">null after</td>"), std::string::npos);  // the residual table
}

TEST(Report, ACalibrationMadeOnOtherDataIsPointedOut) {
  TempDir dir;
  make_run_folder(dir.path());
  auto cal = to_json(perturbed());
  cal["residuals"] = {{"pitch", {{"mean_abs_arcsec", 0.5}, {"points", 10}}}};
  std::ofstream(dir.path() / "calibration.json") << cal.dump();
  ReportOptions opts;
  opts.gnuplot = (dir.path() / "none").string();
  const std::string html = render_report(load_report_input(dir.path()), opts);
  EXPECT_NE(html.find("differs from the residuals recomputed here"), std::string::npos);
  // Table 1 shows the file's block (the one computation); the note what this recording gives.
  EXPECT_NE(html.find("<td>0.50 &plusmn; &ndash;</td>"), std::string::npos);
  EXPECT_NE(html.find("pitch: 56 points, mean "), std::string::npos);
}

// A calibration fitted on the first steps only (points measured after a calibrate step, such as an
// acceptance's verification): Table 1 counts the rows it saw, so it equals the calibrator's block.
TEST(Report, TableOneCountsOnlyTheStepsTheCalibrationWasFittedOn) {
  TempDir dir;
  make_run_folder(dir.path());
  const auto all = compute_residuals(read_samples_csv(dir.path() / "samples.csv"), perturbed(), "differences");
  auto cal = to_json(perturbed());
  cal["fit_last_step"] = 11;  // 6 null and 5 offset dwells: 10 changes
  std::ofstream(dir.path() / "calibration.json") << cal.dump();
  const ReportInput in = load_report_input(dir.path());
  EXPECT_EQ(in.fit_last_step.value(), 11);
  EXPECT_EQ(in.residuals.offset_dwells, 5u);
  EXPECT_EQ(in.residuals.points.size(), 10u);
  EXPECT_LT(in.residuals.points.size(), all.points.size());
  for (const auto& p : in.residuals.points) EXPECT_LE(p.step, 11);
  ReportOptions opts;
  opts.gnuplot = (dir.path() / "none").string();
  EXPECT_NE(render_report(in, opts).find("steps 1 to 11"), std::string::npos);
  cal["fit_last_step"] = "eleven";
  std::ofstream(dir.path() / "calibration.json") << cal.dump();
  EXPECT_NE(fpss::test::error_of<InputError>([&] { load_report_input(dir.path()); }).find("fit_last_step"), std::string::npos);
}

// The verdict sits on top of the page: PASS for a completed run, FAIL with the broken limit for a
// failed check, an acceptance's own verdict, and no verdict for a run that stopped early.
TEST(Report, APassOrFailBannerOpensThePage) {
  TempDir dir;
  make_run_folder(dir.path());
  ReportOptions opts;
  opts.gnuplot = (dir.path() / "none").string();
  auto banner = [&](const nlohmann::json& run) {
    std::ofstream(dir.path() / "run.json") << run.dump();
    const std::string html = render_report(load_report_input(dir.path()), opts);
    const auto at = html.find("<div id=\"verdict\"");
    EXPECT_LT(at, html.find("<nav>"));
    return at == std::string::npos ? std::string() : html.substr(at, html.find("</div>", at) - at);
  };
  auto run = run_json();
  EXPECT_NE(banner(run).find(">PASS<"), std::string::npos);
  run["outcome"] = "failed";
  run["stop_cause"] = "check_failed";
  run["reason"] = "step 4 (check): pitch mean |residual| 405.000 arcsec > 0.8 arcsec";
  const std::string fail = banner(run);
  EXPECT_NE(fail.find(">FAIL<"), std::string::npos);
  EXPECT_NE(fail.find("405.000 arcsec &gt; 0.8 arcsec"), std::string::npos);
  run["stop_cause"] = "aborted";
  run["outcome"] = "interrupted";
  EXPECT_NE(banner(run).find(">INCOMPLETE<"), std::string::npos);
  run["outcome"] = "completed";
  run["acceptance"] = {{"verdict", "fail"}, {"failed", {"jitter_pitch"}}};
  const std::string acc = banner(run);
  EXPECT_NE(acc.find(">FAIL<"), std::string::npos);
  EXPECT_NE(acc.find("jitter_pitch"), std::string::npos);
}

TEST(Report, UsesTheCalibrationRunJsonNames) {
  TempDir dir;
  make_run_folder(dir.path());
  auto run = run_json();
  run["files"]["calibration"] = "calibration-2.json";
  std::ofstream(dir.path() / "run.json") << run.dump();
  EXPECT_THROW(load_report_input(dir.path()), InputError);  // named but absent
  save_coefficients(dir.path() / "calibration-2.json", truth());
  const ReportInput in = load_report_input(dir.path());
  EXPECT_EQ(in.calibration_origin, "calibration-2.json");
  EXPECT_NEAR(in.residuals.pitch.max_abs_arcsec.value(), 0.0, 1e-6);  // the truth fits exactly
  run["files"]["calibration"] = "../elsewhere.json";
  std::ofstream(dir.path() / "run.json") << run.dump();
  EXPECT_THROW(load_report_input(dir.path()), InputError);
}

TEST(Report, WithoutGnuplotTheTablesStillRender) {
  TempDir dir;
  make_run_folder(dir.path());
  ReportOptions opts;
  opts.gnuplot = (dir.path() / "no-such-gnuplot").string();
  const std::string html = read_file(write_report(dir.path(), opts));
  EXPECT_EQ(count(html, "<svg"), 0u);
  EXPECT_NE(html.find("The plots are missing"), std::string::npos);
  EXPECT_NE(html.find("no-such-gnuplot"), std::string::npos);
  const Expected e = expected_residuals(true);
  EXPECT_NE(html.find(fmt::format("{:.2f} &plusmn; {:.2f}", e.mean, e.sd)), std::string::npos);
  EXPECT_NE(html.find("</html>"), std::string::npos);
}

TEST(Report, AFailingGnuplotIsNotedPerPlot) {
  TempDir dir;
  make_run_folder(dir.path());
  const fs::path fake = dir.path() / "fake-gnuplot";
  std::ofstream(fake) << "#!/bin/sh\necho 'line 3: undefined variable: foo' >&2\nexit 1\n";
  fs::permissions(fake, fs::perms::owner_all);
  ReportOptions opts;
  opts.gnuplot = fake.string();
  const std::string html = render_report(load_report_input(dir.path()), opts);
  EXPECT_EQ(count(html, "<svg"), 0u);
  EXPECT_EQ(count(html, "Plot missing ("), 3u);
  EXPECT_NE(html.find("undefined variable: foo"), std::string::npos);
}

TEST(Report, ExtraSectionsAppearInThePage) {
  TempDir dir;
  make_run_folder(dir.path());
  ReportOptions opts;
  opts.gnuplot = (dir.path() / "none").string();
  opts.extra_sections.push_back({"acceptance", "Acceptance", "<p>verdict: <strong>pass</strong></p>"});
  const std::string html = render_report(load_report_input(dir.path()), opts);
  EXPECT_NE(html.find("<section id=\"acceptance\"><h2>Acceptance</h2>\n<p>verdict: <strong>pass</strong></p>"),
            std::string::npos);
  EXPECT_NE(html.find("<a href=\"#acceptance\">Acceptance</a>"), std::string::npos);
}

TEST(Report, AbsoluteMethodResidualsPerDwell) {
  TempDir dir;
  write_recording(dir.path() / "samples.csv", truth(), 0.0, 1);
  const auto samples = read_samples_csv(dir.path() / "samples.csv");
  CoefficientSet c = truth();
  c.alpha[0] += arcsec_to_rad(2.0);  // a 2 arcsec bias on pitch: invisible to changes, seen absolutely
  const auto abs = compute_residuals(samples, c, "absolute");
  ASSERT_EQ(abs.points.size(), 2 * grid().size() + 1);
  EXPECT_NEAR(abs.pitch.mean_abs_arcsec.value(), 2.0, 1e-6);
  EXPECT_NEAR(abs.yaw.max_abs_arcsec.value(), 0.0, 1e-6);
  const auto diff = compute_residuals(samples, c, "differences");
  EXPECT_NEAR(diff.pitch.max_abs_arcsec.value(), 0.0, 1e-6);
}

TEST(Report, BadOrMissingFilesAreClearErrors) {
  TempDir dir;
  auto message = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const InputError& e) {
      return e.what();
    }
    return "(no error)";
  };
  const fs::path none = dir.path() / "no-run";
  EXPECT_NE(message([&] { write_report(none); }).find(none.string()), std::string::npos);

  const fs::path run = dir.path() / "run";
  make_run_folder(run);
  fs::remove(run / "samples.csv");
  EXPECT_NE(message([&] { write_report(run); }).find("samples.csv: missing"), std::string::npos);

  make_run_folder(run);
  fs::remove(run / "calibration.json");
  EXPECT_NE(message([&] { write_report(run); }).find("calibration.json: missing"), std::string::npos);

  make_run_folder(run);
  std::ofstream(run / "calibration.json") << R"({"unit": "FPSS1", "alpha": [1, 2, 3], "beta": []})";
  auto m = message([&] { write_report(run); });
  EXPECT_NE(m.find("calibration.json"), std::string::npos) << m;
  EXPECT_NE(m.find("alpha"), std::string::npos) << m;

  make_run_folder(run);
  auto cal = to_json(perturbed());
  cal["method"] = "guesswork";
  std::ofstream(run / "calibration.json") << cal.dump();
  m = message([&] { write_report(run); });
  EXPECT_NE(m.find("guesswork"), std::string::npos) << m;

  make_run_folder(run);
  {
    std::ofstream f(run / "samples.csv", std::ios::app);
    f << "999,null,999,0,0,12.5,not-a-number,21.5,1\n";
  }
  m = message([&] { write_report(run); });
  EXPECT_NE(m.find("samples.csv"), std::string::npos) << m;
  EXPECT_NE(m.find("counts_beta"), std::string::npos) << m;

  make_run_folder(run);
  std::ofstream(run / "run.json") << "{\"unit\": ";
  m = message([&] { write_report(run); });
  EXPECT_NE(m.find("run.json:1:"), std::string::npos) << m;
  EXPECT_NE(m.find("not valid JSON"), std::string::npos) << m;
  EXPECT_FALSE(fs::exists(run / "report.html"));  // nothing half-written on error
}

TEST(ReportPlot, InlinedSvgHasPrefixedIdsAndNoProlog) {
  const std::string svg =
      "<?xml version=\"1.0\"?>\n<!DOCTYPE svg>\n<svg viewBox='0 0 1 1'>\n<g id=\"gnuplot_canvas\">"
      "<defs><circle id='gpDot' r='1'/><clipPath id='c1'/></defs>"
      "<use xlink:href='#gpDot' clip-path='url(#c1)'/><text>valid='yes'</text><g id='k'/><g id='k'/></g></svg>\n";
  const std::string out = inline_svg(svg, "p7_");
  EXPECT_EQ(out.rfind("<svg", 0), 0u) << out;
  EXPECT_NE(out.find("id=\"p7_gnuplot_canvas\""), std::string::npos);
  EXPECT_NE(out.find("id='p7_gpDot'"), std::string::npos);
  EXPECT_NE(out.find("href='#p7_gpDot'"), std::string::npos);
  EXPECT_NE(out.find("url(#p7_c1)"), std::string::npos);
  EXPECT_NE(out.find("valid='yes'"), std::string::npos);  // not an id attribute: untouched
  EXPECT_NE(out.find("<g id='p7_k'/><g id='p7_k-2'/>"), std::string::npos) << out;  // repeated ids made unique
  EXPECT_EQ(out.find("<?xml"), std::string::npos);
  EXPECT_EQ(gnuplot_quote("it's\nfine"), "it''s fine");
}

}  // namespace
}  // namespace fpss
