#include "calib/reduction.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "base/errors.h"
#include "calib/outliers.h"
#include "calib/quantisation.h"

namespace fpss {

void OutlierSummary::add(const Dwell& d) {
  frames += d.frames();
  any.outlier_frames += d.outliers;
  alpha.outlier_frames += d.outliers_alpha;
  beta.outlier_frames += d.outliers_beta;
}

double OutlierSummary::worst_share() const { return std::max(alpha.share(frames), beta.share(frames)); }

nlohmann::json OutlierSummary::to_json() const {
  nlohmann::ordered_json rule = {{"applied", applied}, {"threshold_sigma", OutlierRule{}.threshold_sigma}};
  rule["count_noise_counts"] = count_noise_counts ? nlohmann::ordered_json(*count_noise_counts) : nlohmann::ordered_json();
  rule["count_noise_source"] = count_noise_source;
  nlohmann::ordered_json j = {{"frames", frames}, {"outlier_frames", any.outlier_frames}, {"share", any.share(frames)}};
  j["pitch"] = {{"outlier_frames", alpha.outlier_frames}, {"share", alpha.share(frames)}};
  j["yaw"] = {{"outlier_frames", beta.outlier_frames}, {"share", beta.share(frames)}};
  j["rule"] = rule;
  return j;
}

OutlierSummary OutlierSummary::from_json(const nlohmann::json& j, const std::string& origin) {
  auto bad = [&](const std::string& what) { return InputError(fmt::format("{}: outliers: {}", origin, what)); };
  auto count = [&](const nlohmann::json& o, const char* key) -> size_t {
    if (!o.is_object() || !o.contains(key) || !o[key].is_number_unsigned()) {
      throw bad(fmt::format("\"{}\" must be a whole number >= 0", key));
    }
    return o[key].get<size_t>();
  };
  if (!j.is_object()) throw bad("expected an object");
  OutlierSummary s;
  s.frames = count(j, "frames");
  s.any.outlier_frames = count(j, "outlier_frames");
  if (!j.contains("pitch") || !j.contains("yaw")) throw bad("\"pitch\" and \"yaw\" are required");
  s.alpha.outlier_frames = count(j["pitch"], "outlier_frames");
  s.beta.outlier_frames = count(j["yaw"], "outlier_frames");
  if (!j.contains("rule") || !j["rule"].is_object()) throw bad("\"rule\" must be an object");
  const auto& r = j["rule"];
  if (!r.contains("applied") || !r["applied"].is_boolean()) throw bad("rule.applied must be true or false");
  s.applied = r["applied"].get<bool>();
  if (r.contains("count_noise_counts") && !r["count_noise_counts"].is_null()) {
    if (!r["count_noise_counts"].is_number() || !(r["count_noise_counts"].get<double>() >= 0)) {
      throw bad("rule.count_noise_counts must be a number >= 0 or null");
    }
    s.count_noise_counts = r["count_noise_counts"].get<double>();
  }
  if (r.contains("count_noise_source") && r["count_noise_source"].is_string()) {
    s.count_noise_source = r["count_noise_source"].get<std::string>();
  }
  const size_t most = std::max(s.alpha.outlier_frames, s.beta.outlier_frames);
  if (s.any.outlier_frames > s.frames || most > s.any.outlier_frames) {
    throw bad("counts are inconsistent (per axis <= outlier_frames <= frames)");
  }
  return s;
}

ReductionOptions OutlierSummary::options() const {
  ReductionOptions o;
  o.reject_outliers = applied;
  o.count_noise_counts = count_noise_counts;
  o.count_noise_source = count_noise_source;
  return o;
}

ReductionOptions reduction_options_of(const nlohmann::json& extra, const std::string& origin) {
  if (!extra.is_object() || !extra.contains("outliers")) return {};
  return OutlierSummary::from_json(extra["outliers"], origin).options();
}

bool count_scatters(const Dwell& d, CountScatter out[2]) {
  if (d.samples < 2 || !d.whole_counts_alpha || !d.whole_counts_beta) return false;
  out[0] = {d.counts_alpha, d.sd_counts_alpha * d.sd_counts_alpha, d.samples};
  out[1] = {d.counts_beta, d.sd_counts_beta * d.sd_counts_beta, d.samples};
  return true;
}

std::vector<OutlierAxes> flag_count_outliers(const FrameColumns& t, double floor_counts) {
  std::vector<OutlierAxes> out(t.size());
  const OutlierRule rule = count_outlier_rule(floor_counts);
  std::vector<double> v(t.size());
  for (const bool alpha : {true, false}) {
    const auto& col = alpha ? t.counts_alpha : t.counts_beta;
    for (size_t i = 0; i < t.size(); ++i) {
      const bool dwell = t.phase[i] == Phase::null || t.phase[i] == Phase::offset;
      v[i] = dwell ? col[i] : std::numeric_limits<double>::quiet_NaN();
    }
    const OutlierFlags f = flag_outliers(v, t.step, rule);
    for (size_t i = 0; i < t.size(); ++i) (alpha ? out[i].alpha : out[i].beta) = f.outlier[i];
  }
  return out;
}

namespace {

// The count noise from the within-dwell scatter of whole-count dwells (none: unknown).
std::optional<double> scatter_noise(const std::vector<Dwell>& dwells) {
  std::vector<CountScatter> sc;
  for (const Dwell& d : dwells) {
    CountScatter two[2];
    if (count_scatters(d, two)) sc.insert(sc.end(), two, two + 2);
  }
  return estimate_count_noise(sc.data(), sc.size());
}

}  // namespace

Reduction reduce(const SampleTable& t, const ReductionOptions& opts) {
  FrameColumns f = t.frames();
  const std::vector<double> temp = t.has_column("temperature_c") ? t.numeric_column("temperature_c") : std::vector<double>{};
  if (!temp.empty()) f.temperature_c = &temp;
  return reduce(f, opts);
}

Reduction reduce(const FrameColumns& t, const ReductionOptions& opts) {
  Reduction r;
  r.outliers.applied = opts.reject_outliers;
  if (opts.reject_outliers) {
    // Unknown noise: a first pass with the rounding's floor keeps gross spikes out of the
    // within-dwell scatter the noise is estimated from.
    std::optional<double> s = opts.count_noise_counts;
    std::string source = opts.count_noise_source;
    if (!s) {
      r.flags = flag_count_outliers(t, count_outlier_floor(std::nullopt));
      s = scatter_noise(average_dwells(t, r.flags));
      source = s ? "within-dwell scatter" : "unknown";
    }
    if (s) r.flags = flag_count_outliers(t, count_outlier_floor(s));
    r.outliers.count_noise_counts = s;
    r.outliers.count_noise_source = source;
  }
  r.dwells = average_dwells(t, r.flags);
  for (const Dwell& d : r.dwells) r.outliers.add(d);
  return r;
}

}  // namespace fpss
