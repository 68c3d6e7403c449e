// fpss-stand calibrate: fit both transfer functions to a samples recording and write a coefficient file.
#include <fmt/format.h>

#include <cstdio>
#include <memory>
#include <optional>

#include "base/clock.h"
#include "base/errors.h"
#include "base/text_file.h"
#include "calib/calibrator.h"
#include "calib/coefficients.h"
#include "calib/monte_carlo.h"
#include "calib/reference_calibration.h"
#include "calib/report.h"
#include "calib/samples.h"
#include "calib/streaming.h"
#include "procedures/recorder.h"
#include "stand/catalogue/run_file.h"
#include "stand/cli/commands.h"
#include "stand/cli/file_hints.h"
#include "stand/cli/help.h"
#include "stand/cli/file_options.h"

namespace fpss::cli {

namespace {

// --reference: the file, and what the recording's run.json (beside it, when there is one) says:
// the mount that takes its sensor-frame angles to the gimbal's axes, and whether the run already
// applied a reference (then only its u is added, and only for the same file).
void use_reference(CalibrationOptions& opts, const std::string& file, const std::string& data) {
  opts.reference = load_reference_calibration(file);
  opts.correct_reference = true;
  const auto dir = std::filesystem::path(data).parent_path();
  if (!std::filesystem::exists(dir / "run.json")) return;
  const RunFile run = read_run_file(dir);
  if (run.stand && run.stand->settings.is_object() && run.stand->settings.contains("axes")) {
    const auto& axes = run.stand->settings["axes"];
    auto axis = [&](const char* key, AxisMapping::SensorAxis& a, double& sign) {
      const std::string v = axes.value(key, "");
      sign = v.starts_with("-") ? -1.0 : 1.0;
      a = v.ends_with("beta") ? AxisMapping::beta : AxisMapping::alpha;
    };
    axis("pitch", opts.mount.pitch_axis, opts.mount.pitch_sign);
    axis("yaw", opts.mount.yaw_axis, opts.mount.yaw_sign);
  }
  if (!run.reference) return;
  if (run.reference->sha256 != opts.reference->sha256) {
    throw InputError(fmt::format("--reference {}: the run in {} already corrected its reference angles with {} "
                                 "(sha256 {}); give that file, or none",
                                 file, dir.string(), run.reference->file, run.reference->sha256));
  }
  opts.correct_reference = false;  // corrected by the run: its u only
}

}  // namespace

void add_calibrate(CLI::App& app, Runner& run) {
  struct Opts {
    std::string data, out, init, method = "differences", truth, unit, reference;
    std::optional<double> count_noise;
    std::optional<size_t> monte_carlo;
    uint64_t monte_carlo_seed = 1;
    bool json = false;
    FileOptions files;
  };
  auto o = std::make_shared<Opts>();
  auto* sub = app.add_subcommand(
      "calibrate",
      "Fit the pitch (alpha) and yaw (beta) transfer functions to a null-to-offset recording; "
      "prints the Table-1-style summary and writes the coefficient file");
  expect_file(sub, o->files.input(sub, "--data", o->data, "samples file (CSV, the stand's recording format)")->required(),
              o->data, FileKind::samples);
  o->files.output(sub, "--out", o->out, "coefficient file to write (JSON), with a residuals block")->required();
  expect_file(sub, o->files.input(sub, "--init", o->init, "a coefficient file tried as a start besides the global search"),
              o->init, FileKind::coefficients);
  sub->add_option("--method", o->method,
                  "differences: C2..C8 on changes null <-> offset, C1 from the null condition (the paper's); "
                  "absolute: C1..C8 on absolute reference angles")
      ->check(CLI::IsMember({"differences", "absolute"}))
      ->capture_default_str();
  expect_file(sub,
              o->files.input(sub, "--truth", o->truth,
                             "a coefficient file with the known truth (simulations): prints how far the fit is from it"),
              o->truth, FileKind::coefficients);
  sub->add_option("--count-noise-counts", o->count_noise,
                  "expected sensor noise per frame before whole-count rounding, counts (default: the --init "
                  "file's count_noise_counts, else estimated from the within-dwell scatter)")
      ->check(CLI::NonNegativeNumber);
  o->files.input(sub, "--reference", o->reference,
                 "the reference's calibration (JSON, docs/formats.md): corrects a raw recording's reference "
                 "angles and adds its uncertainty to the calibration's");
  sub->add_option("--monte-carlo", o->monte_carlo,
                  "check the uncertainty budget by N Monte Carlo trials (JCGM 101): the calibrated angle's 95 % "
                  "interval at the budget's angle against the GUM's U, in calibration.json monte_carlo")
      ->check(CLI::Range(size_t{100}, size_t{10'000'000}));
  sub->add_option("--monte-carlo-seed", o->monte_carlo_seed, "the Monte Carlo draws' seed")->capture_default_str();
  sub->add_option("--unit", o->unit, "unit name written to the coefficient file (default: from --init or --truth)");
  sub->add_flag("--json", o->json,
                "print {\"file\": OUT, \"calibration\": <the coefficient file's content>} instead of the summary");
  examples(sub, {"fpss-stand simulate --out rec.csv --truth calib/data/published/a-5-fpss2.json",
                 "fpss-stand calibrate --data rec.csv --out cal.json --truth calib/data/published/a-5-fpss2.json "
                 "--monte-carlo 100000"});
  sub->callback([o, &run] {
    run = [o] {
      o->files.check();
      CalibrationOptions opts;
      opts.method = *parse_method(o->method);
      std::optional<CoefficientSet> truth;
      if (!o->init.empty()) opts.init = load_coefficients(o->init);
      if (!o->truth.empty()) truth = load_coefficients(o->truth);
      opts.unit = !o->unit.empty() ? o->unit
                  : opts.init       ? opts.init->unit
                  : truth           ? truth->unit
                                    : std::string();
      if (o->count_noise) {
        opts.count_noise_counts = *o->count_noise;
        opts.count_noise_source = "command line";
      }
      if (!o->reference.empty()) use_reference(opts, o->reference, o->data);
      // Row by row: only the dwells' sums are kept, whatever the recording's length.
      const CalibrationReport rep = calibrate_csv(o->data, opts);

      CoefficientSet set = rep.coefficients();
      set.extra["calibrated_at"] = utc_now_iso();
      if (!o->init.empty()) set.extra["init"] = o->init;
      std::optional<TruthComparison> cmp;
      if (truth) {
        cmp = compare_to_truth(rep, *truth);
        set.extra["truth_comparison"] = {
            {"truth", o->truth},
            {"pitch", {{"max_abs_arcsec", cmp->pitch.max_abs_arcsec}, {"rms_arcsec", cmp->pitch.rms_arcsec}}},
            {"yaw", {{"max_abs_arcsec", cmp->yaw.max_abs_arcsec}, {"rms_arcsec", cmp->yaw.rms_arcsec}}}};
      }
      std::optional<MonteCarloCheck> mc;
      if (o->monte_carlo) {
        mc = monte_carlo_check(rep, opts, *o->monte_carlo, o->monte_carlo_seed);
        set.extra["monte_carlo"] = mc->to_json();
      }
      save_coefficients(o->out, set);

      if (o->json) {
        const nlohmann::json j = {{"file", o->out}, {"calibration", to_json(set)}};
        std::printf("%s\n", j.dump(1).c_str());
        return 0;
      }
      std::string text = summary_text(rep);
      if (cmp) text += truth_text(*cmp, o->truth);
      // Without the check, say that the budget's U is the GUM's first-order figure and how to test it.
      text += mc ? monte_carlo_text(*mc)
                 : "\nthe uncertainty budget (U, calibration.json uncertainties) is the GUM's, to first order and "
                   "not checked: --monte-carlo 100000 checks it (JCGM 101)\n";
      text += fmt::format("\nwrote {}\n", o->out);
      std::fputs(text.c_str(), stdout);
      return 0;
    };
  });
}

}  // namespace fpss::cli
