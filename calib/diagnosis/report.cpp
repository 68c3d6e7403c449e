// The data behind the diagnosis's report: the residual against every factor before and after the
// causes, and the residual map over the field. The page itself is stand/report/diagnosis_page.
#include <algorithm>
#include <cmath>

#include "calib/diagnosis/diagnosis.h"
#include "calib/diagnosis/internal.h"
#include "calib/diagnosis/model.h"

namespace fpss {
namespace {

using diag::Contribution;
using diag::Recording;
using diag::StepKind;
using diag::Use;

// The causes' contributions, rebuilt from their reported parameters.
Contribution contributions(const Recording& r, const std::vector<EffectResult>& causes) {
  Contribution sum, k;
  sum.resize(r.n);
  k.resize(r.n);
  for (const auto& c : causes) {
    auto cand = diag::make_candidate(c.name);
    if (!cand) continue;
    EffectParams p;
    p.name = c.name;
    if (c.name == "coefficients") {
      CoefficientSet set = r.model;
      set.alpha = c.params.at("alpha").get<AxisCoeffs>();
      set.beta = c.params.at("beta").get<AxisCoeffs>();
      p.coefficients = set;
    } else {
      for (auto it = c.params.begin(); it != c.params.end(); ++it) p.params[it.key()] = it.value().get<double>();
    }
    cand->set(p);
    cand->contribute(r, k);
    for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) sum.v[a][i] += k.v[a][i];
  }
  return sum;
}

}  // namespace

DiagnosisFigures diagnosis_figures(const SampleTable& data, const CoefficientSet& model, const Diagnosis& d,
                                   const DiagnosisOptions& opts) {
  const Recording r = diag::prepare(DiagnosisColumns::of(data), model, opts);
  return diag::figures(r, contributions(r, d.causes));
}

namespace diag {

DiagnosisFigures figures(const Recording& r, const Contribution& c) {
  DiagnosisFigures f;
  struct Spec {
    const char* name;
    const char* xlabel;
  };
  std::vector<Spec> specs = {{"angle", "own axis angle, arcsec"},
                             {"cross_angle", "other axis angle, arcsec"},
                             {"slew_rate", "own axis rate, arcsec/s (slews)"},
                             {"approach_direction", "direction of motion of the axis"},
                             {"time", "time, s"},
                             {"time_since_move", "time since the move ended, s (dwells)"}};
  if (r.has_temperature) specs.push_back({"temperature", "temperature, C"});
  const size_t stride = std::max<size_t>(1, r.n / 20000);
  for (const auto& s : specs) {
    DiagnosisFactorSeries fs;
    fs.factor = s.name;
    fs.xlabel = s.xlabel;
    const std::string n = s.name;
    for (int a = 0; a < 2; ++a) {
      for (size_t i = 0; i < r.n; i += stride) {
        if (r.use[i] == Use::excluded) continue;
        const bool moving = r.steps[r.step_of[i]].kind == StepKind::motion;
        double x;
        if (n == "angle") x = r.ref[a][i];
        else if (n == "cross_angle") x = r.ref[1 - a][i];
        else if (n == "slew_rate") { if (!moving) continue; x = r.vel[a][i]; }
        else if (n == "approach_direction") x = r.dir[a][i];
        else if (n == "time") x = r.t[i];
        else if (n == "time_since_move") { if (!std::isfinite(r.since_move[i])) continue; x = r.since_move[i]; }
        else { if (!std::isfinite(r.temp[i])) continue; x = r.temp[i]; }
        fs.x[a].push_back(x);
        fs.before[a].push_back(r.res[a][i]);
        fs.after[a].push_back(r.res[a][i] - c.v[a][i]);
      }
    }
    if (!fs.x[0].empty() || !fs.x[1].empty()) f.factors.push_back(std::move(fs));
  }
  for (const auto& s : r.steps) {
    if (s.kind != StepKind::dwell) continue;
    DiagnosisMapPoint p;
    double m = 0;
    for (size_t i = s.begin; i < s.end; ++i) {
      if (r.outlier[i] || near_move(r, i)) continue;
      m += 1;
      p.pitch_arcsec += r.ref[0][i];
      p.yaw_arcsec += r.ref[1][i];
      for (int a = 0; a < 2; ++a) { p.before[a] += r.res[a][i]; p.after[a] += r.res[a][i] - c.v[a][i]; }
    }
    if (m == 0) continue;
    p.pitch_arcsec /= m;
    p.yaw_arcsec /= m;
    for (int a = 0; a < 2; ++a) { p.before[a] /= m; p.after[a] /= m; }
    f.map.push_back(p);
  }
  return f;
}

}  // namespace diag
}  // namespace fpss
