#include "calib/outliers.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

namespace fpss {
namespace {

double median_of(std::vector<double>& v) {
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  double m = v[mid];
  if (v.size() % 2 == 0) m = 0.5 * (m + *std::max_element(v.begin(), v.begin() + mid));
  return m;
}

}  // namespace

double StepValues::median() const {
  if (frames == 0) return NAN;
  // Sorted positions mid (and mid - 1 for an even count), as median_of takes them.
  const uint64_t mid = frames / 2;
  auto value_at = [&](uint64_t k) {
    uint64_t seen = 0;
    for (const auto& [v, n] : values) {
      seen += n;
      if (seen > k) return v;
    }
    return values.rbegin()->first;
  };
  double m = value_at(mid);
  if (frames % 2 == 0) m = 0.5 * (m + value_at(mid - 1));
  return m;
}

double StepOutlierScreen::pool_step(const StepValues& step) {
  if (step.frames < static_cast<uint64_t>(std::max(0, rule_.min_step_frames)) || step.frames == 0) return NAN;
  const double m = step.median();
  for (const auto& [v, n] : step.values) {
    deviations_.values[std::fabs(v - m)] += n;
    deviations_.frames += n;
  }
  return m;
}

double StepOutlierScreen::robust_sigma() const {
  if (deviations_.frames == 0) return 0.0;
  return std::max(1.4826 * deviations_.median(), rule_.min_sigma);
}

OutlierFlags flag_outliers(const std::vector<double>& residual, const std::vector<int64_t>& step,
                           const OutlierRule& rule) {
  if (residual.size() != step.size()) throw std::invalid_argument("flag_outliers: residual and step differ in size");
  OutlierFlags out;
  out.outlier.assign(residual.size(), false);
  std::map<int64_t, std::vector<size_t>> rows_of;
  for (size_t i = 0; i < step.size(); ++i)
    if (std::isfinite(residual[i])) rows_of[step[i]].push_back(i);

  std::vector<double> centre(residual.size(), NAN), deviations, tmp;
  deviations.reserve(residual.size());
  for (const auto& [id, rows] : rows_of) {
    if (static_cast<int>(rows.size()) < rule.min_step_frames) continue;
    tmp.clear();
    for (size_t i : rows) tmp.push_back(residual[i]);
    const double m = median_of(tmp);
    for (size_t i : rows) {
      centre[i] = m;
      deviations.push_back(std::fabs(residual[i] - m));
    }
  }
  if (deviations.empty()) return out;
  out.robust_sigma = std::max(1.4826 * median_of(deviations), rule.min_sigma);
  if (!(out.robust_sigma > 0)) return out;
  const double limit = rule.threshold_sigma * out.robust_sigma;
  for (size_t i = 0; i < residual.size(); ++i) {
    if (std::isnan(centre[i]) || std::fabs(residual[i] - centre[i]) <= limit) continue;
    out.outlier[i] = true;
    ++out.count;
    if (out.steps.empty() || out.steps.back() != step[i]) out.steps.push_back(step[i]);
  }
  std::sort(out.steps.begin(), out.steps.end());
  out.steps.erase(std::unique(out.steps.begin(), out.steps.end()), out.steps.end());
  return out;
}

}  // namespace fpss
