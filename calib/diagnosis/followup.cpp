// How a planned run separates rival effects and bounds unseen ones (calib/diagnosis/followup.h).
#include "calib/diagnosis/followup.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "base/errors.h"
#include "calib/diagnosis/internal.h"
#include "calib/diagnosis/model.h"
#include "calib/units.h"

namespace fpss {

using ojson = nlohmann::ordered_json;

namespace {

// A refitted transfer function's C1..C8 per axis (GAP.json's params `alpha` and `beta`), each a
// finite number no larger than a coefficient file's (calib/coefficients.h); none when absent.
std::optional<CoefficientSet> refitted_set(const ojson& effect) {
  const ojson& params = effect.value("params", ojson::object());
  CoefficientSet s;
  for (auto [key, axis] : {std::pair{"alpha", &s.alpha}, std::pair{"beta", &s.beta}}) {
    const ojson& c = params.is_object() ? params.value(key, ojson()) : ojson();
    if (!c.is_array() || c.size() != axis->size()) return std::nullopt;
    for (size_t k = 0; k < axis->size(); ++k) {
      if (!c[k].is_number() || !(std::abs(c[k].get<double>()) <= kMaxAbsCoefficient)) {
        throw InputError(fmt::format("coefficients: params.{}[{}] is not a coefficient (a finite number of at most {:g})",
                                     key, k, kMaxAbsCoefficient));
      }
      (*axis)[k] = c[k].get<double>();
    }
  }
  return s;
}

// Why a named refit is not yet a measurement over the calibrated range (empty when it is): the
// sixths of the range its rows miss on either axis (coefficients.cpp, range_sections).
std::string partly_measured(const EffectResult& e) {
  if (e.name != "coefficients" || !e.notes.contains("range_sections")) return {};
  std::string missed;
  for (const auto& [key, axis] : {std::pair{"alpha", "pitch"}, std::pair{"beta", "yaw"}}) {
    const ojson& s = e.notes["range_sections"].value(key, ojson::array());
    const auto reached = std::count(s.begin(), s.end(), true);
    if (reached < static_cast<long>(s.size())) {
      missed += fmt::format("{}{} reaches {} of {}", missed.empty() ? "" : ", ", axis, reached, s.size());
    }
  }
  if (missed.empty()) return {};
  return fmt::format("named over part of the calibrated range only ({} sixths): elsewhere the refit is the model's "
                     "sinusoids changed as fitted here, an extrapolation; offsets over the whole range measure it",
                     missed);
}

}  // namespace

EffectParams effect_from_json(const ojson& effect) {
  EffectParams p;
  if (!effect.is_object() || !effect.contains("name") || !effect["name"].is_string()) {
    throw InputError("an effect needs a name");
  }
  p.name = effect["name"].get<std::string>();
  const auto& names = diagnosis_effect_names();
  if (std::find(names.begin(), names.end(), p.name) == names.end()) {
    throw InputError(fmt::format("unknown effect \"{}\"", p.name));
  }
  if (effect.contains("params") && effect["params"].is_object()) {
    for (auto it = effect["params"].begin(); it != effect["params"].end(); ++it) {
      if (it.value().is_number()) p.params[it.key()] = it.value().get<double>();
    }
  }
  if (p.name == "coefficients") p.coefficients = refitted_set(effect);
  return p;
}

std::vector<CandidateStatus> candidate_status(const Diagnosis& d, double materiality_arcsec) {
  std::vector<CandidateStatus> out;
  // Seen only beyond what the causes explain: with no gap left, a candidate scoring well against
  // none scores so by standing in for a cause.
  const double left = d.cause == "none" ? d.gap_before_arcsec : d.gap_after_all_arcsec;
  const bool gap_left = left > 1.5 * d.noise_floor_arcsec;
  for (const std::string& name : diagnosis_effect_names()) {
    CandidateStatus s;
    s.name = name;
    const bool named = std::any_of(d.causes.begin(), d.causes.end(), [&](const EffectResult& c) { return c.name == name; });
    const bool ambiguous = std::any_of(d.ambiguous.begin(), d.ambiguous.end(), [&](const Diagnosis::AmbiguousSet& a) {
      return std::find(a.members.begin(), a.members.end(), name) != a.members.end();
    });
    const auto no = std::find_if(d.not_observable.begin(), d.not_observable.end(),
                                 [&](const NotObservable& n) { return n.name == name; });
    const auto e = std::find_if(d.effects.begin(), d.effects.end(), [&](const EffectResult& r) { return r.name == name; });
    if (e != d.effects.end()) s.limit_arcsec = e->limit_arcsec;
    if (ambiguous) {
      s.status = "ambiguous";
      s.why = "in a set of look-alikes the recording cannot tell apart";
    } else if (const std::string part = e != d.effects.end() ? partly_measured(*e) : ""; named && !part.empty()) {
      s.status = "unbounded";
      s.why = part;
    } else if (named) {
      s.status = "named";
    } else if (no != d.not_observable.end()) {
      s.status = "unbounded";
      s.why = "not observable: " + no->reason;
    } else if (e == d.effects.end()) {
      s.status = "unbounded";
      s.why = "not fitted";
    } else if (gap_left && e->score < -kAmbiguityMargin) {
      s.status = "unbounded";
      s.why = fmt::format("seen but not named: it scores {:.1f} against none while a gap is left", e->score);
    } else if (e->limit_arcsec <= materiality_arcsec) {
      s.status = "bounded";
      s.why = fmt::format("would have been seen at {:.4f} arcsec where it acts (materiality {:.4f})", e->limit_arcsec,
                          materiality_arcsec);
    } else {
      s.status = "unbounded";
      s.why = fmt::format("would be seen only from {:.4f} arcsec where it acts, above the materiality {:.4f}",
                          e->limit_arcsec, materiality_arcsec);
    }
    out.push_back(std::move(s));
  }
  return out;
}

struct PlannedRun::Impl {
  diag::Recording r;
  double noise = 0;
};

PlannedRun::PlannedRun(DiagnosisColumns planned, const CoefficientSet& model, const DiagnosisOptions& opts,
                       double noise_arcsec)
    : impl_(std::make_unique<Impl>(Impl{diag::prepare(std::move(planned), model, opts), noise_arcsec})) {
  if (!(noise_arcsec > 0)) throw InputError("a planned run needs the noise floor of one frame (> 0)");
}
PlannedRun::~PlannedRun() = default;
PlannedRun::PlannedRun(PlannedRun&&) noexcept = default;

RangeSections PlannedRun::range_sections() const { return diag::range_sections(impl_->r); }

size_t PlannedRun::rows() const { return impl_->r.n; }
size_t PlannedRun::heldout_rows() const { return impl_->r.heldout_rows.size(); }

double PlannedRun::expected_log_lr(const EffectParams& truth, const std::string& rival) const {
  return expected_log_lr(truth, std::vector<std::string>{rival});
}

double PlannedRun::expected_log_lr(const EffectParams& truth, const std::vector<std::string>& rivals) const {
  const diag::Recording& r = impl_->r;
  auto t = diag::make_candidate(truth.name);
  if (!t) throw InputError(fmt::format("no forward model for {}", truth.name));
  std::vector<std::unique_ptr<diag::Candidate>> b;
  for (const std::string& name : rivals) {
    b.push_back(diag::make_candidate(name));
    if (!b.back()) throw InputError(fmt::format("no forward model for {}", name));
  }
  t->set(truth);
  diag::Contribution target;
  target.resize(r.n);
  t->contribute(r, target);
  // Several rivals together are fitted in turn, each to what the others leave (backfitting): the
  // rivals a nested candidate is weighed against (a bias and a scale factor) are nearly orthogonal
  // on a plan's rows, and a few passes settle them.
  std::vector<diag::Contribution> each(b.size());
  for (auto& c : each) c.resize(r.n);
  diag::Contribution fitted, left;
  fitted.resize(r.n);
  left.resize(r.n);
  const int passes = b.size() > 1 ? 5 : 1;
  for (int pass = 0; pass < passes; ++pass) {
    for (size_t k = 0; k < b.size(); ++k) {
      for (int a = 0; a < 2; ++a) {
        for (size_t i = 0; i < r.n; ++i) left.v[a][i] = target.v[a][i] - (fitted.v[a][i] - each[k].v[a][i]);
      }
      b[k]->restart();
      b[k]->fit(r, left, r.fit_rows);
      diag::Contribution mine;
      mine.resize(r.n);
      b[k]->contribute(r, mine);
      for (int a = 0; a < 2; ++a) {
        for (size_t i = 0; i < r.n; ++i) fitted.v[a][i] += mine.v[a][i] - each[k].v[a][i];
      }
      each[k] = std::move(mine);
    }
  }
  double ss = 0;
  for (uint32_t i : r.heldout_rows) {
    if (r.use[i] == diag::Use::excluded) continue;
    for (int a = 0; a < 2; ++a) {
      const double e = static_cast<double>(target.v[a][i]) - fitted.v[a][i];
      ss += e * e;
    }
  }
  return ss / (2 * impl_->noise * impl_->noise);
}

double PlannedRun::separation(const EffectParams& a, const EffectParams& b) const {
  return std::min(expected_log_lr(a, b.name), expected_log_lr(b, a.name));
}

double PlannedRun::limit_arcsec(const std::string& effect, size_t other_heldout_rows) const {
  EffectResult res;
  res.name = effect;
  auto c = diag::make_candidate(effect);
  if (!c) return std::numeric_limits<double>::infinity();
  res.parameters = c->parameters();
  res.params = c->params();  // every key, at zero
  const double N = 2.0 * static_cast<double>(impl_->r.heldout_rows.size() + other_heldout_rows);
  double acting = std::numeric_limits<double>::infinity();
  diag::statistical_limit(impl_->r, res, impl_->noise, N, &acting);
  return acting;
}

}  // namespace fpss
