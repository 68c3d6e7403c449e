// Two effects at once: joint fits, the search for a second effect, and why two effects look alike.
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "calib/diagnosis/internal.h"

namespace fpss::diag {
namespace {

// One effect is a special case of the other: a refitted transfer function contains any bias
// (C1) and scale factor (C1, C2, C3, C6 scaled together). Such pairs are never fitted.
bool contained(const std::string& a, const std::string& b) {
  auto is = [&](const char* x, const char* y) { return (a == x && b == y) || (a == y && b == x); };
  return is("coefficients", "bias") || is("coefficients", "scale_factor");
}

// Two candidates fitted jointly: alternating least squares (each on the residual less the
// other) for their nonlinear parameters, then one least-squares solve over the linear columns of
// both (alternation alone converges slowly when the two are correlated), until the fit rows' sum
// of squares settles.
struct JointFit {
  EffectResult e[2];
  std::unique_ptr<Candidate> c[2];  // fitted: their contributions make the pair's (rebuilt when kept)
  double score = 0;
};

// Mean square over both axes of residual - k1 - k2 on `rows`.
double mean_square2(const Recording& r, const Contribution& k1, const Contribution& k2, const std::vector<uint32_t>& rows) {
  double s = 0;
  for (uint32_t i : rows) {
    for (int a = 0; a < 2; ++a) {
      const double e = r.res[a][i] - k1.v[a][i] - k2.v[a][i];
      s += e * e;
    }
  }
  return rows.empty() ? 0.0 : s / (2.0 * static_cast<double>(rows.size()));
}

// One least-squares solve over the linear columns of both candidates (those that have them),
// the other's contribution held; their contributions are then rewritten.
void joint_linear_step(const Recording& r, Candidate* c[2], Contribution* k[2]) {
  const int mq[2] = {c[0]->columns(), c[1]->columns()};
  const int m = mq[0] + mq[1];
  if (m == 0) return;
  const Eigen::VectorXd w = solve_columns(r.fit_rows, m, [&](uint32_t i, int a, double* v) {
    double target = r.res[a][i];
    for (int q = 0; q < 2; ++q) target -= mq[q] == 0 ? k[q]->v[a][i] : c[q]->column_offset(r, i, a);
    if (mq[0] > 0) c[0]->column_values(r, i, a, v);
    if (mq[1] > 0) c[1]->column_values(r, i, a, v + mq[0]);
    return target;
  });
  for (int q = 0, at = 0; q < 2; at += mq[q], ++q) {
    if (mq[q] == 0) continue;
    c[q]->set_linear(std::vector<double>(w.data() + at, w.data() + at + mq[q]));
    c[q]->contribute(r, *k[q]);
  }
}

JointFit joint_fit(const Recording& r, const Scored& first, const std::string& name2, double ms0, double N) {
  auto c1 = first.cand->clone();
  auto c2 = diag::make_candidate(name2);
  // Two contributions only (the memory of a large recording): each fit's target is written into
  // the buffer its own contribution then overwrites.
  Contribution k1 = first.contribution(r), k2;
  k2.resize(r.n);
  Candidate* c[2] = {c1.get(), c2.get()};
  Contribution* k[2] = {&k1, &k2};
  // A temperature's zero point and a constant offset (a bias, or the C1 of a refitted transfer
  // function) trade against each other: by the emulator's convention the profile starts at t0_c,
  // so t0_c is held at the first temperature reading.
  const bool offset = first.result.name == "bias" || name2 == "bias" || first.result.name == "coefficients" ||
                      name2 == "coefficients";
  if (offset && r.has_temperature) {
    double t_first = 0;
    for (size_t i = 0; i < r.n; ++i) if (std::isfinite(r.temp[i])) { t_first = r.temp[i]; break; }
    for (Candidate* q : c) if (q->name() == "temperature") q->hold("t0_c", t_first);
  }
  double prev = std::numeric_limits<double>::infinity(), best = prev;
  std::unique_ptr<Candidate> best_c[2];
  for (int it = 0; it < 20; ++it) {
    // The second was first fitted on what the first's single fit left, which had to absorb the
    // second too: once the linear parts of both have been solved together (the first pass), both
    // search afresh (a refitted transfer function may otherwise stay in the basin that compromise
    // led it into).
    if (it == 1) { c1->restart(); c2->restart(); }
    for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) k2.v[a][i] = static_cast<float>(r.res[a][i] - k1.v[a][i]);
    c2->fit(r, k2, r.fit_rows);
    c2->contribute(r, k2);
    // The first's single fit had to absorb the second too; once the second is in, it starts
    // afresh.
    if (it == 0) c1->restart();
    for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) k1.v[a][i] = static_cast<float>(r.res[a][i] - k2.v[a][i]);
    c1->fit(r, k1, r.fit_rows);
    c1->contribute(r, k1);
    joint_linear_step(r, c, k);
    const double sse = mean_square2(r, k1, k2, r.fit_rows);
    if (sse < best) {
      best = sse;
      best_c[0] = c1->clone();
      best_c[1] = c2->clone();
    }
    // The fresh search after the first pass may start higher: it is not a sign of convergence.
    if (it != 1 && prev - sse <= 1e-7 * sse) break;
    prev = sse;
  }
  // The restarts may have led somewhere worse than a state already seen: that state is kept.
  if (best < mean_square2(r, k1, k2, r.fit_rows)) {
    c1 = std::move(best_c[0]);
    c2 = std::move(best_c[1]);
    c[0] = c1.get();
    c[1] = c2.get();
    c1->contribute(r, k1);
    c2->contribute(r, k2);
  }
  JointFit j;
  const double ms = mean_square2(r, k1, k2, r.heldout_rows);
  const double fit_ms = mean_square2(r, k1, k2, r.fit_rows);
  j.score = penalised(ms, ms0, c1->parameters() + c2->parameters(), N);
  for (int q = 0; q < 2; ++q) {
    j.e[q].name = c[q]->name();
    j.e[q].params = c[q]->params();
    j.e[q].parameters = c[q]->parameters();
    j.e[q].notes = c[q]->notes();
    j.e[q].degenerate = c[q]->degenerate();
    j.e[q].fit_rms_arcsec = std::sqrt(fit_ms);  // jointly
    j.e[q].heldout_rms_arcsec = std::sqrt(ms);
    j.e[q].score = j.score;
  }
  j.c[0] = std::move(c1);
  j.c[1] = std::move(c2);
  return j;
}

// Firsts: the three best held-out scores and the two best in-sample fits (with two effects
// at once a single fit can be biased by the other effect so that it fails on the held-out
// rows while still taking the most off the fit rows). An in-sample fit may be degenerate: a
// refitted transfer function made to absorb a second effect too (a settling of several arcsec)
// grows implausible sinusoids alone, and is sound once the second is in (the joint fit restarts
// it; a pair with a degenerate member is never kept).
std::vector<const Scored*> pair_firsts(const std::vector<Scored>& all, double N) {
  std::vector<const Scored*> firsts;
  auto add_first = [&](const Scored* f) {
    if (f->result.name != "none" && std::find(firsts.begin(), firsts.end(), f) == firsts.end()) firsts.push_back(f);
  };
  for (size_t k = 0, m = 0; k < all.size() && m < 3; ++k) {
    if (all[k].result.name == "none" || !all[k].result.degenerate.empty()) continue;
    add_first(&all[k]);
    ++m;
  }
  std::vector<const Scored*> by_fit;
  for (const auto& s1 : all) if (s1.result.name != "none") by_fit.push_back(&s1);
  std::sort(by_fit.begin(), by_fit.end(), [&](const Scored* a, const Scored* b) {
    return penalised(a->result.fit_rms_arcsec * a->result.fit_rms_arcsec, 1.0, a->result.parameters, N) <
           penalised(b->result.fit_rms_arcsec * b->result.fit_rms_arcsec, 1.0, b->result.parameters, N);
  });
  for (size_t k = 0; k < by_fit.size() && k < 2; ++k) add_first(by_fit[k]);
  return firsts;
}

// Around each first, the others screened on what it leaves, the three most promising fitted
// jointly with it; the best-scoring pair with no degenerate member.
std::optional<JointFit> best_pair(const Recording& r, const std::vector<Scored>& all,
                                  const std::vector<const Scored*>& firsts, double ms0, double N) {
  std::optional<JointFit> pair;
  for (const Scored* fp : firsts) {
    const Scored& f = *fp;
    std::vector<std::pair<double, std::string>> screened;
    {
    // Two buffers (a large recording's memory): the first's contribution and the second's,
    // which first holds what the first leaves. The joint linear step rewrites the first's when
    // it has linear columns; it is then written afresh for the next.
    Contribution k1 = f.contribution(r), k2;
    k2.resize(r.n);
    bool k1_is_single = true;
    for (const auto& s2 : all) {
      const std::string& name2 = s2.result.name;
      if (name2 == "none" || name2 == f.result.name || contained(f.result.name, name2)) continue;
      // One pass: the other fitted on what the first leaves, then both linear parts solved
      // together (a single's fit can be a compromise only a joint solve undoes).
      auto c1 = f.cand->clone();
      auto c2 = diag::make_candidate(name2);
      if (!k1_is_single) f.cand->contribute(r, k1);
      for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) k2.v[a][i] = static_cast<float>(r.res[a][i] - k1.v[a][i]);
      c2->fit(r, k2, r.fit_rows);
      c2->contribute(r, k2);
      Candidate* cc[2] = {c1.get(), c2.get()};
      Contribution* kk[2] = {&k1, &k2};
      joint_linear_step(r, cc, kk);
      k1_is_single = c1->columns() == 0;
      double ms = 0;
      for (uint32_t i : r.heldout_rows) {
        for (int a = 0; a < 2; ++a) {
          const double e = r.res[a][i] - k1.v[a][i] - k2.v[a][i];
          ms += e * e;
        }
      }
      screened.push_back({penalised(ms / N, ms0, c1->parameters() + c2->parameters(), N), name2});
    }
    }  // the screening's buffers are freed before the joint fits
    std::sort(screened.begin(), screened.end());
    if (screened.size() > 3) screened.resize(3);
    for (const auto& sc : screened) {
      JointFit j = joint_fit(r, f, sc.second, ms0, N);
        if (!j.e[0].degenerate.empty() || !j.e[1].degenerate.empty()) continue;
      if (!pair || j.score < pair->score) pair = std::move(j);
    }
  }
  return pair;
}

}  // namespace

// Why two effects can look alike, for the ambiguity note.
std::string why_alike(const std::string& a, const std::string& b) {
  auto is = [&](const char* x, const char* y) { return (a == x && b == y) || (a == y && b == x); };
  if (is("backlash", "settling")) {
    return "a settling with a time constant much longer than the dwells acts like backlash at rest; slews (moving, "
           "no settling) or longer dwells tell them apart";
  }
  if (is("drift", "temperature") || is("bias", "temperature")) {
    return "the temperature follows time (or barely changes) in this recording; a non-monotonic temperature profile "
           "tells them apart";
  }
  if (is("scale_factor", "coefficients") || is("bias", "coefficients")) {
    return "a refitted transfer function absorbs any offset or scale; more offsets or a wider field tell them apart";
  }
  if (is("settling", "time_skew")) {
    return "a settling gone within the first frames after arrival is what a sensor that lags the reference shows "
           "there (the end of the move); slews, where a lag grows with the rate, tell them apart";
  }
  if (is("boresight_roll", "axis_nonorthogonality")) {
    return "both turn pitch into yaw; only a roll also turns yaw into pitch, which needs yaw offsets";
  }
  if (a == "none" || b == "none") return "the effect is barely above the noise of this recording";
  return "the held-out data barely tells them apart";
}

Separation separation(const std::string& a, const std::string& b) {
  auto is = [&](const char* x, const char* y) { return (a == x && b == y) || (a == y && b == x); };
  auto has = [&](const char* x) { return a == x || b == x; };
  if (has("time_skew")) {
    return {"slew_rate", "slews at several rates in both directions: a time shift grows with the rate, the others do not"};
  }
  if (is("backlash", "settling")) {
    return {"time_since_move", "approaches from both sides with long dwells: backlash stays for the whole dwell, "
                               "settling decays"};
  }
  if (has("backlash")) {
    return {"approach_direction", "approaches from both sides at the same points: only backlash changes sign with the "
                                  "side"};
  }
  if (has("settling")) {
    return {"time_since_move", "dwells of several lengths after moves: settling decays with the time since arrival"};
  }
  if (is("drift", "temperature") || (has("temperature") && has("bias"))) {
    return {"time", "repeated nulls over a longer time: drift keeps growing while the temperature turns or holds"};
  }
  if (has("drift")) return {"time", "repeated nulls over time"};
  if (has("coefficients")) {
    return {"angle", "offsets over the whole calibrated range at a finer step: a transfer-function change is not "
                     "proportional to the angle"};
  }
  if (has("boresight_roll") || has("axis_nonorthogonality")) {
    return {"cross_angle", "offsets on both axes: a roll turns yaw into pitch too, a non-orthogonality does not"};
  }
  return {"angle", "offsets over the whole calibrated range on both axes"};
}

void second_effect(const Recording& r, const std::vector<Scored>& all, const Scored& best, double ms0, double N,
                   double material, Diagnosis& d, Contribution& combined) {
  auto single = [&](const std::string& n) -> const Scored& {
    for (const auto& s : all) if (s.result.name == n) return s;
    return all.front();
  };
  std::vector<const Scored*> firsts = pair_firsts(all, N);
  std::optional<JointFit> pair = best_pair(r, all, firsts, ms0, N);
  // The best pair's members are searched around too, until that changes nothing: a pair found
  // around a catch-all (a refitted transfer function or a temperature, which hold any constant)
  // may be a simpler effect's stand-in paired with the right second (bias and backlash found as
  // coefficients and backlash when neither bias nor backlash alone was among the firsts); around
  // the second, the simpler first is screened, and fewer parameters score better.
  while (pair) {
    std::vector<const Scored*> more;
    for (const EffectResult& e : pair->e) {
      const Scored* s = &single(e.name);
      if (std::find(firsts.begin(), firsts.end(), s) == firsts.end()) more.push_back(s);
    }
    if (more.empty()) break;
    firsts.insert(firsts.end(), more.begin(), more.end());
    std::optional<JointFit> other = best_pair(r, all, more, ms0, N);
    if (!other || !(other->score < pair->score)) break;
    pair = std::move(other);
  }
  // Kept when it scores better than the best single and its second member is material: it
  // takes at least 0.1 x noise floor^2 off the held-out mean square its first leaves alone.
  bool keep = pair && pair->score < best.result.score;
  EffectResult e1, e2;
  if (keep) {
    // In order: the one that alone explains more first.
    e1 = pair->e[0];
    e2 = pair->e[1];
    if (single(e2.name).result.score < single(e1.name).result.score) std::swap(e1, e2);
    const double alone = single(e1.name).result.heldout_rms_arcsec;
    keep = alone * alone - pair->e[1].heldout_rms_arcsec * pair->e[1].heldout_rms_arcsec >= material;
  }
  if (keep) {
    const Scored& lead = single(e1.name);
    e1.fit_rms_arcsec = lead.result.fit_rms_arcsec;  // the first's own figures, alone
    e1.heldout_rms_arcsec = lead.result.heldout_rms_arcsec;
    e1.score = lead.result.score;
    d.cause = e1.name;
    d.gap_after_arcsec = lead.result.heldout_rms_arcsec;
    d.causes = {e1, e2};
    d.gap_after_all_arcsec = e2.heldout_rms_arcsec;
    combined.resize(r.n);
    Contribution k;
    k.resize(r.n);
    for (const auto& c : pair->c) {
      c->contribute(r, k);
      for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) combined.v[a][i] += k.v[a][i];
    }
  }
}

}  // namespace fpss::diag
