// The diagnosis's steps shared between its files: scoring, pairs, where, verdict.
#pragma once
#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include "calib/diagnosis/diagnosis.h"
#include "calib/diagnosis/model.h"

namespace fpss::diag {

// Least squares over `rows` (both axes) of y ~ v . w for m columns: fill(i, a, v) writes row i's
// column values on axis a into v[0..m) and returns its y. The columns are evaluated row by row as
// the sums are made (no column arrays: a large recording's memory); a tiny ridge keeps a column that
// is zero on every row (an effect silent there) from making the normal equations singular.
template <typename Fill>
Eigen::VectorXd solve_columns(const std::vector<uint32_t>& rows, int m, Fill&& fill) {
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(m, m);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(m);
  std::vector<double> v(static_cast<size_t>(m));
  for (uint32_t i : rows) {
    for (int a = 0; a < 2; ++a) {
      const double y = fill(i, a, v.data());
      for (int x = 0; x < m; ++x) {
        const double vx = v[x];
        if (vx == 0) continue;
        b(x) += vx * y;
        for (int z = 0; z <= x; ++z) G(x, z) += vx * v[z];
      }
    }
  }
  G = G.selfadjointView<Eigen::Lower>();
  G.diagonal().array() += 1e-12 * (G.diagonal().maxCoeff() + 1e-30);
  return G.ldlt().solve(b);
}

// Mean square over both axes of (residual - contribution) on `rows`.
double mean_square(const Recording& r, const Contribution* c, const std::vector<uint32_t>& rows);

double penalised(double ms, double ms0, int k, double N);

// One candidate fitted and scored. Its contribution is not kept (eleven of them would be most of
// the diagnosis's memory): it is rebuilt from the fitted candidate when needed.
struct Scored {
  std::unique_ptr<Candidate> cand;  // null for none
  EffectResult result;
  Contribution contribution(const Recording& r) const {
    Contribution c;
    c.resize(r.n);
    if (cand) cand->contribute(r, c);
    return c;
  }
};

// The rows of a joint diagnosis's recordings that keep a level of their own: every recording
// after the first that runs on its own clock (JointClock::own: a bench started again, whose
// drift or temperature went on unseen between runs). Empty otherwise.
std::vector<std::pair<size_t, size_t>> levelled_parts(const Recording& r);
// The candidate `name` ("none": the levels alone) for this recording: with a level per axis for
// each of levelled_parts(r), fitted with it, when there are any; make_candidate(name) otherwise
// (null for none).
std::unique_ptr<Candidate> make_candidate(const std::string& name, const Recording& r);

// The candidates a recording cannot show, and why (observability.cpp).
struct Observability {
  std::vector<NotObservable> missing;
  bool ok(const std::string& name) const {
    return std::none_of(missing.begin(), missing.end(), [&](const NotObservable& m) { return m.name == name; });
  }
};
Observability observability(const Recording& r);

// Why two effects can look alike, for the ambiguity note.
std::string why_alike(const std::string& a, const std::string& b);
// What separates two look-alikes: the `where` factor along which their predictions part, and the
// kind of run that exercises it (the designer's moves, docs/diagnosis.md).
struct Separation {
  std::string factor, measurement;
};
Separation separation(const std::string& a, const std::string& b);

// The second effect around the singles `all` (sorted by score, `best` the cause): when a pair is
// kept, it becomes d's causes and `combined` their joint contribution.
void second_effect(const Recording& r, const std::vector<Scored>& all, const Scored& best, double ms0, double N,
                   double material, Diagnosis& d, Contribution& combined);

std::vector<WhereEntry> where_of(const Recording& r, const std::vector<float> e_in[2], double noise_arcsec,
                                 nlohmann::ordered_json* flexible = nullptr);
nlohmann::ordered_json where_json(const std::vector<WhereEntry>& w);

// Pooled within-step scatter of one sample about its step mean (dwells with three or more
// frames, outliers left out), RMS over both axes; NaN when no dwell has three frames.
double within_step_scatter(const Recording& r, const std::vector<float> e[2]);
// The report's data (diagnosis_figures) from the prepared recording and the causes' contribution.
DiagnosisFigures figures(const Recording& r, const Contribution& causes);
nlohmann::ordered_json detection_limit(const Recording& r, const EffectResult& e, double noise, double N);
// The time constant settling's statistical limit is stated for.
inline constexpr double kSettlingLimitTau_s = 0.5;
// With `acting_rms_arcsec`: the RMS of the effect at its limit over the held-out rows where it acts
// (a tenth of its peak or more), the worst of its magnitudes; +inf when it acts nowhere.
nlohmann::ordered_json statistical_limit(const Recording& r, const EffectResult& e, double noise, double N,
                                         double* acting_rms_arcsec = nullptr);
// Each magnitude of `e` at which its held-out mean square reaches `need` (N: both axes' held-out rows).
nlohmann::ordered_json limit_for(const Recording& r, const EffectResult& e, double noise, double N, double need,
                                 double* acting_rms_arcsec = nullptr);
void decide_verdict(const Recording& r, Diagnosis& d, const nlohmann::ordered_json& flexible);

}  // namespace fpss::diag
