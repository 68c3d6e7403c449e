// Gauge repeatability and reproducibility by the ANOVA method (AIAG MSA, 4th ed.): parts x appraisers x repeats.
#pragma once
#include <cstddef>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

namespace fpss {

// A crossed study: y[part][appraiser][repeat], every cell with the same number of repeats (>= 2).
// An appraiser is whatever is crossed with the parts: a stand, an operator.
struct GaugeStudy {
  std::vector<std::vector<std::vector<double>>> y;
};

struct AnovaTerm {
  double ss = 0, df = 0;
  double ms() const { return df > 0 ? ss / df : 0.0; }
};

struct GaugeRr {
  size_t parts = 0, appraisers = 0, repeats = 0;
  AnovaTerm part, appraiser, interaction, repeatability, total;
  // Standard deviations of the variance components (a negative estimate is taken as 0). The
  // interaction stays in the model always (never pooled into repeatability): no F test decides.
  double ev = 0, av = 0, interaction_sd = 0, grr = 0, pv = 0, tv = 0;
  double grr_percent_tv = 0;                  // 100 GRR / TV
  std::optional<double> grr_percent_tolerance;  // 100 x 6 GRR / tolerance, when a tolerance is given
  int ndc = 0;                                // number of distinct categories: floor(1.41 PV / GRR)
  nlohmann::ordered_json to_json() const;
};

// std::invalid_argument for a study that is not crossed and balanced (fewer than two parts,
// appraisers or repeats, ragged cells, a non-finite value) or a tolerance that is not positive.
GaugeRr gauge_rr(const GaugeStudy& s, std::optional<double> tolerance = std::nullopt);

}  // namespace fpss
