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

std::vector<FrameCentre> step_centres(const std::vector<double>& v, const OutlierRule& rule, std::vector<double>* pooled) {
  std::vector<FrameCentre> c(v.size());
  if (v.empty() || static_cast<int>(v.size()) < rule.min_step_frames) return c;
  std::vector<double> tmp;
  if (rule.local_half_window <= 0) {
    tmp = v;
    const double m = median_of(tmp);
    for (size_t q = 0; q < v.size(); ++q) {
      c[q].centre = m;
      if (pooled) pooled->push_back(std::fabs(v[q] - m));
    }
    return c;
  }
  // The median of the frame and its neighbours, as many on each side (up to k) as the step has:
  // it keeps a step change and anything monotonic (a settling decay) exactly, while a spike never
  // is the median. The deviation of a noise-only frame from such a median is smaller than from the
  // step's median, by a factor that depends on the window (Gaussian: 0.462, 0.732, 0.817 of sigma
  // for 3, 5, 7 frames): the robust sigma is taken from deviations divided by it. A frame is judged
  // by its own deviation (in the tail the median hardly depends on the frame, so the deviation is
  // as wide as the noise).
  // A NaN frame is absent (a frame judged again without its flagged neighbours): it keeps its
  // place, so the window still spans the same time, and is left out of the median.
  const size_t k = static_cast<size_t>(rule.local_half_window), n = v.size();
  for (size_t q = 1; q + 1 < n; ++q) {
    const size_t h = std::min({k, q, n - 1 - q});
    tmp.clear();
    for (size_t w = q - h; w <= q + h; ++w)
      if (std::isfinite(v[w])) tmp.push_back(v[w]);
    if (tmp.empty()) continue;
    const double m = median_of(tmp);
    const double f = h == 1 ? 0.462 : h == 2 ? 0.732 : h == 3 ? 0.817 : 1.0 - 0.183 * 3.0 / static_cast<double>(h);
    c[q].centre = m;
    if (pooled && std::isfinite(v[q])) pooled->push_back(std::fabs(v[q] - m) / f);
  }
  // A step's first and last frames (not pooled): the line through the running medians of their
  // two nearest neighbours, extrapolated to them (the median of 3 and of 5 frames, which a spike
  // never is, the judged frame's own included), against a limit widened by the extrapolation's own
  // scatter (x1.5); with three frames, the middle one's median. A line through the raw neighbours
  // (Theil-Sen of three) was pulled by a spike among them and flagged clean edge frames.
  if (n >= 3) {
    c[0] = {n >= 4 ? 2 * c[1].centre - c[2].centre : c[1].centre, true};
    c[n - 1] = {n >= 4 ? 2 * c[n - 2].centre - c[n - 3].centre : c[n - 2].centre, true};
  }
  return c;
}

std::vector<bool> judge_step(const std::vector<double>& v, const OutlierRule& rule, double sigma) {
  std::vector<bool> out(v.size(), false);
  if (!(sigma > 0)) return out;
  const double limit = rule.threshold_sigma * sigma;
  // How far a frame lies beyond its limit (> 1: an outlier).
  auto excess = [&](double x, const FrameCentre& c) {
    if (!std::isfinite(x) || std::isnan(c.centre)) return 0.0;
    return std::fabs(x - c.centre) / ((c.edge ? 1.5 : 1.0) * limit);
  };
  if (rule.local_half_window <= 0) {
    const std::vector<FrameCentre> c = step_centres(v, rule);
    for (size_t q = 0; q < v.size(); ++q) out[q] = excess(v[q], c[q]) > 1.0;
    return out;
  }
  // A spike in a steep decay moves its neighbours' running median by one frame's decay, which
  // may exceed the limit: the worst frame is taken first and replaced by the line between its
  // nearest frames not taken (the windows keep their span in time), then the step is judged again.
  std::vector<double> w(v);
  for (size_t round = 0; round < v.size(); ++round) {
    const std::vector<FrameCentre> c = step_centres(w, rule);
    size_t worst = v.size();
    double most = 1.0;
    for (size_t q = 0; q < w.size(); ++q) {
      if (out[q]) continue;
      const double e = excess(w[q], c[q]);
      if (e > most) { most = e; worst = q; }
    }
    if (worst == v.size()) break;
    out[worst] = true;
    size_t lo = worst, hi = worst;
    while (lo > 0 && out[lo]) --lo;
    while (hi + 1 < w.size() && out[hi]) ++hi;
    const bool has_lo = !out[lo], has_hi = !out[hi];
    if (!has_lo && !has_hi) break;  // every frame taken
    for (size_t q = has_lo ? lo + 1 : 0; q < (has_hi ? hi : w.size()); ++q) {
      w[q] = !has_lo ? w[hi] : !has_hi ? w[lo]
                     : w[lo] + (w[hi] - w[lo]) * static_cast<double>(q - lo) / static_cast<double>(hi - lo);
    }
  }
  return out;
}

void StepOutlierScreen::pool_step(const std::vector<double>& frames) {
  std::vector<double> dev;
  step_centres(frames, rule_, &dev);
  for (const double d : dev) deviations_.add(d);
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
  std::vector<double> deviations, vals;
  if (pooled) {
    deviations.reserve(residual.size());
    for (const auto& [id, rows] : rows_of) {
      vals.clear();
      for (size_t i : rows) vals.push_back(residual[i]);
      step_centres(vals, rule, &deviations);
    }
  } else {
    deviations = reading_differences(residual, rows_of, rule, shared_reading);
  }
  if (deviations.empty()) return out;
  out.robust_sigma = std::max(1.4826 * median_of(deviations), rule.min_sigma);
  if (!(out.robust_sigma > 0)) return out;
  for (const auto& [id, rows] : rows_of) {
    vals.clear();
    for (size_t i : rows) vals.push_back(residual[i]);
    const std::vector<bool> f = judge_step(vals, rule, out.robust_sigma);
    for (size_t q = 0; q < rows.size(); ++q) {
      if (!f[q]) continue;
      out.outlier[rows[q]] = true;
      ++out.count;
      if (out.steps.empty() || out.steps.back() != id) out.steps.push_back(id);
    }
  }
  std::sort(out.steps.begin(), out.steps.end());
  out.steps.erase(std::unique(out.steps.begin(), out.steps.end()), out.steps.end());
  return out;
}

}  // namespace fpss
