#include "calib/outliers.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>
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

// |difference| / sqrt(2) between neighbouring frames of a step that have readings of their own:
// each such pair holds two independent draws of the sensor's and the reference's noise, whoever
// else shares those readings.
std::vector<double> reading_differences(const std::vector<double>& residual,
                                        const std::map<int64_t, std::vector<size_t>>& rows_of, const OutlierRule& rule,
                                        const std::vector<bool>& shared_reading) {
  std::vector<double> out;
  for (const auto& [id, rows] : rows_of) {
    if (static_cast<int>(rows.size()) < rule.min_step_frames) continue;
    for (size_t q = 1; q < rows.size(); ++q) {
      if (shared_reading[rows[q]]) continue;
      out.push_back(std::fabs(residual[rows[q]] - residual[rows[q - 1]]) / std::sqrt(2.0));
    }
  }
  return out;
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
                           const OutlierRule& rule, const std::vector<bool>& shared_reading) {
  if (residual.size() != step.size()) throw std::invalid_argument("flag_outliers: residual and step differ in size");
  if (!shared_reading.empty() && shared_reading.size() != residual.size()) {
    throw std::invalid_argument("flag_outliers: shared_reading and residual differ in size");
  }
  OutlierFlags out;
  out.outlier.assign(residual.size(), false);
  std::map<int64_t, std::vector<size_t>> rows_of;
  for (size_t i = 0; i < step.size(); ++i)
    if (std::isfinite(residual[i])) rows_of[step[i]].push_back(i);

  // With reading ids the sigma comes from differences between readings (below), not from these.
  const bool pooled = shared_reading.empty();
  std::vector<double> centre(residual.size(), NAN), deviations, tmp;
  std::vector<bool> edge(residual.size(), false);
  if (pooled) deviations.reserve(residual.size());
  for (const auto& [id, rows] : rows_of) {
    if (static_cast<int>(rows.size()) < rule.min_step_frames) continue;
    if (rule.local_half_window > 0) {
      // The median of the frame and its neighbours, as many on each side (up to k) as the step
      // has: it keeps a step change and anything monotonic exactly, while a spike never is the
      // median. The deviation of a noise-only frame from such a median is smaller than from the
      // step's median, by a factor that depends on the window (Gaussian: 0.462, 0.732, 0.817 of
      // sigma for 3, 5, 7 frames): the robust sigma is taken from deviations divided by it. A frame
      // is judged by its own deviation (in the tail the median hardly depends on the frame, so the
      // deviation is as wide as the noise). First and last frames are not judged.
      const size_t k = static_cast<size_t>(rule.local_half_window);
      for (size_t q = 0; q < rows.size(); ++q) {
        const size_t h = std::min({k, q, rows.size() - 1 - q});
        if (h == 0) {
          // A step's first or last frame: the line through its k nearest neighbours (Theil-Sen:
          // the median of their pairwise slopes), extrapolated to it, judged against a limit
          // widened by the extrapolation's own scatter (x1.5).
          const size_t m = std::min(k, rows.size() - 1);
          if (m < 2) continue;
          std::vector<double> xs, ys, slopes;
          for (size_t j = 1; j <= m; ++j) {
            const size_t w = q == 0 ? j : q - j;
            xs.push_back(q == 0 ? static_cast<double>(j) : -static_cast<double>(j));
            ys.push_back(residual[rows[w]]);
          }
          for (size_t u = 0; u < xs.size(); ++u)
            for (size_t v = u + 1; v < xs.size(); ++v) slopes.push_back((ys[v] - ys[u]) / (xs[v] - xs[u]));
          const double slope = median_of(slopes);
          for (size_t u = 0; u < xs.size(); ++u) ys[u] -= slope * xs[u];
          centre[rows[q]] = median_of(ys);
          edge[rows[q]] = true;
          continue;
        }
        tmp.clear();
        for (size_t w = q - h; w <= q + h; ++w) tmp.push_back(residual[rows[w]]);
        const double m = median_of(tmp);
        const double f = h == 1 ? 0.462 : h == 2 ? 0.732 : h == 3 ? 0.817 : 1.0 - 0.183 * 3.0 / static_cast<double>(h);
        centre[rows[q]] = m;
        if (pooled) deviations.push_back(std::fabs(residual[rows[q]] - m) / f);
      }
      continue;
    }
    tmp.clear();
    for (size_t i : rows) tmp.push_back(residual[i]);
    const double m = median_of(tmp);
    for (size_t i : rows) {
      centre[i] = m;
      if (pooled) deviations.push_back(std::fabs(residual[i] - m));
    }
  }
  if (!pooled) deviations = reading_differences(residual, rows_of, rule, shared_reading);
  if (deviations.empty()) return out;
  out.robust_sigma = std::max(1.4826 * median_of(deviations), rule.min_sigma);
  if (!(out.robust_sigma > 0)) return out;
  const double limit = rule.threshold_sigma * out.robust_sigma;
  for (size_t i = 0; i < residual.size(); ++i) {
    if (std::isnan(centre[i]) || std::fabs(residual[i] - centre[i]) <= (edge[i] ? 1.5 : 1.0) * limit) continue;
    out.outlier[i] = true;
    ++out.count;
    if (out.steps.empty() || out.steps.back() != step[i]) out.steps.push_back(step[i]);
  }
  std::sort(out.steps.begin(), out.steps.end());
  out.steps.erase(std::unique(out.steps.begin(), out.steps.end()), out.steps.end());
  return out;
}

}  // namespace fpss
