#include "calib/msa.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace fpss {
namespace {

void check(const GaugeStudy& s) {
  const auto bad = [](const std::string& why) { return std::invalid_argument("gauge study: " + why); };
  if (s.y.size() < 2) throw bad("at least two parts are needed");
  const size_t o = s.y[0].size();
  if (o < 2) throw bad("at least two appraisers are needed");
  const size_t r = s.y[0][0].size();
  if (r < 2) throw bad("at least two repeats are needed (repeatability is their scatter)");
  for (size_t i = 0; i < s.y.size(); ++i) {
    if (s.y[i].size() != o) throw bad(fmt::format("part {} has {} appraisers, part 1 has {}", i + 1, s.y[i].size(), o));
    for (size_t j = 0; j < o; ++j) {
      if (s.y[i][j].size() != r) {
        throw bad(fmt::format("part {}, appraiser {}: {} repeats, the first cell has {}", i + 1, j + 1, s.y[i][j].size(), r));
      }
      for (double v : s.y[i][j]) {
        if (!std::isfinite(v)) throw bad(fmt::format("part {}, appraiser {}: a value is not finite", i + 1, j + 1));
      }
    }
  }
}

double sd_of(double variance) { return std::sqrt(std::max(0.0, variance)); }

}  // namespace

GaugeRr gauge_rr(const GaugeStudy& s, std::optional<double> tolerance) {
  check(s);
  if (tolerance && !(*tolerance > 0 && std::isfinite(*tolerance))) {
    throw std::invalid_argument("gauge study: the tolerance must be a positive number");
  }
  GaugeRr g;
  const size_t p = s.y.size(), o = s.y[0].size(), r = s.y[0][0].size();
  g.parts = p;
  g.appraisers = o;
  g.repeats = r;
  const double P = static_cast<double>(p), O = static_cast<double>(o), R = static_cast<double>(r);
  // Means: grand, per part, per appraiser, per cell.
  std::vector<double> part_mean(p, 0.0), app_mean(o, 0.0), cell(p * o, 0.0);
  double grand = 0;
  for (size_t i = 0; i < p; ++i) {
    for (size_t j = 0; j < o; ++j) {
      double c = 0;
      for (double v : s.y[i][j]) c += v;
      cell[i * o + j] = c / R;
      part_mean[i] += c / (O * R);
      app_mean[j] += c / (P * R);
      grand += c / (P * O * R);
    }
  }
  for (size_t i = 0; i < p; ++i) g.part.ss += O * R * (part_mean[i] - grand) * (part_mean[i] - grand);
  for (size_t j = 0; j < o; ++j) g.appraiser.ss += P * R * (app_mean[j] - grand) * (app_mean[j] - grand);
  for (size_t i = 0; i < p; ++i) {
    for (size_t j = 0; j < o; ++j) {
      const double inter = cell[i * o + j] - part_mean[i] - app_mean[j] + grand;
      g.interaction.ss += R * inter * inter;
      for (double v : s.y[i][j]) {
        g.repeatability.ss += (v - cell[i * o + j]) * (v - cell[i * o + j]);
        g.total.ss += (v - grand) * (v - grand);
      }
    }
  }
  g.part.df = P - 1;
  g.appraiser.df = O - 1;
  g.interaction.df = (P - 1) * (O - 1);
  g.repeatability.df = P * O * (R - 1);
  g.total.df = P * O * R - 1;
  // Variance components from the expected mean squares of the random-effects model.
  const double ev2 = g.repeatability.ms();
  const double int2 = (g.interaction.ms() - ev2) / R;
  const double av2 = (g.appraiser.ms() - g.interaction.ms()) / (P * R);
  const double pv2 = (g.part.ms() - g.interaction.ms()) / (O * R);
  g.ev = sd_of(ev2);
  g.interaction_sd = sd_of(int2);
  g.av = sd_of(av2);
  g.pv = sd_of(pv2);
  g.grr = std::sqrt(g.ev * g.ev + g.av * g.av + g.interaction_sd * g.interaction_sd);
  g.tv = std::sqrt(g.grr * g.grr + g.pv * g.pv);
  g.grr_percent_tv = g.tv > 0 ? 100 * g.grr / g.tv : 0.0;
  if (tolerance) g.grr_percent_tolerance = 100 * 6 * g.grr / *tolerance;
  g.ndc = g.grr > 0 ? static_cast<int>(std::floor(1.41 * g.pv / g.grr)) : 0;
  return g;
}

nlohmann::ordered_json GaugeRr::to_json() const {
  const auto term = [](const AnovaTerm& t) { return nlohmann::ordered_json{{"ss", t.ss}, {"df", t.df}, {"ms", t.ms()}}; };
  nlohmann::ordered_json j = {{"parts", parts}, {"appraisers", appraisers}, {"repeats", repeats}};
  j["anova"] = {{"part", term(part)},
                {"appraiser", term(appraiser)},
                {"interaction", term(interaction)},
                {"repeatability", term(repeatability)},
                {"total", term(total)}};
  j["sd"] = {{"ev", ev}, {"av", av}, {"interaction", interaction_sd}, {"grr", grr}, {"pv", pv}, {"tv", tv}};
  j["grr_percent_tv"] = grr_percent_tv;
  j["grr_percent_tolerance"] = grr_percent_tolerance ? nlohmann::ordered_json(*grr_percent_tolerance) : nlohmann::ordered_json();
  j["ndc"] = ndc;
  return j;
}

}  // namespace fpss
