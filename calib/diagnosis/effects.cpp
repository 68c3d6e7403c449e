// The candidate effects: each one's forward model (the emulator's convention, fixtures/bench.cpp)
// and its least-squares fit on the fit rows. Residual = model(counts) - reference, arcsec.
#include <fmt/format.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "calib/diagnosis/model.h"
#include "calib/units.h"

namespace fpss::diag {
namespace {

using Rows = std::vector<uint32_t>;
using ojson = nlohmann::ordered_json;

double get(const EffectParams& p, const std::string& key) {
  auto it = p.params.find(key);
  return it == p.params.end() ? 0.0 : it->second;
}

// A value per axis under the emulator's names for it, pitch_<unit> and yaw_<unit>.
ojson per_axis_params(const std::string& unit, const double* k) {
  return {{"pitch_" + unit, k[0]}, {"yaw_" + unit, k[1]}};
}
void set_per_axis(const EffectParams& p, const std::string& unit, double* k) {
  k[0] = get(p, "pitch_" + unit);
  k[1] = get(p, "yaw_" + unit);
}

// Least squares of one scale factor: target ~ c * x over rows, both axes pooled when asked.
double ratio(double sxy, double sxx) { return sxx > 0 ? sxy / sxx : 0.0; }

// The same for one axis's target against a factor x(i) of the row.
template <typename X>
double slope(const Rows& rows, const std::vector<float>& target, X x) {
  double sxy = 0, sxx = 0;
  for (uint32_t i : rows) {
    const double xi = x(i);
    sxy += xi * target[i];
    sxx += xi * xi;
  }
  return ratio(sxy, sxx);
}

// Columns with one weight per axis: the factor x on axis a's own column, 0 on the other's.
void own_axis_columns(int a, double x, double* v) {
  v[0] = a == 0 ? x : 0.0;
  v[1] = a == 1 ? x : 0.0;
}

// An effect of one weight per axis on a factor of the row: the weight is the least-squares slope
// of the target on the factor, and the effect is linear in it.
template <typename Self>
class PerAxisSlope : public NamedCandidate<Self> {
 public:
  PerAxisSlope(const char* name, const char* unit) : NamedCandidate<Self>(name, 2), unit_(unit) {}
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    for (int a = 0; a < 2; ++a) k_[a] = slope(rows, tg.v[a], [&](uint32_t i) { return Self::factor(r, i); });
  }
  void contribute(const Recording& r, Contribution& out) const override {
    for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) out.v[a][i] = k_[a] * Self::factor(r, i);
  }
  ojson params() const override { return per_axis_params(unit_, k_); }
  void set(const EffectParams& p) override { set_per_axis(p, unit_, k_); }
  int columns() const override { return 2; }  // the factor, one per axis
  void column_values(const Recording& r, size_t i, int a, double* v) const override {
    own_axis_columns(a, Self::factor(r, i), v);
  }
  void set_linear(const std::vector<double>& w) override { k_[0] = w[0]; k_[1] = w[1]; }

 private:
  const char* unit_;
  double k_[2] = {0, 0};
};

// ------------------------------------------------------------------ bias: a constant per axis
class Bias : public PerAxisSlope<Bias> {
 public:
  Bias() : PerAxisSlope("bias", "arcsec") {}
  static double factor(const Recording& r, size_t i) { return 1.0; }
};

// ------------------------------------------------------------------ drift: rate * t (bench time)
class Drift : public PerAxisSlope<Drift> {
 public:
  Drift() : PerAxisSlope("drift", "arcsec_per_s") {}
  static double factor(const Recording& r, size_t i) { return r.t[i]; }
};

// ------------------------------------------------------------------ scale_factor
// The gimbal reads (1 + ppm 1e-6) x the true angle: the sensor sees ref / (1 + ppm 1e-6).
class ScaleFactor : public NamedCandidate<ScaleFactor> {
 public:
  ScaleFactor() : NamedCandidate("scale_factor", 2) {}
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    for (int a = 0; a < 2; ++a) {
      // residual = c * ref, c = 1/(1+k) - 1
      const double c = slope(rows, tg.v[a], [&](uint32_t i) { return r.ref[a][i]; });
      ppm_[a] = (1.0 / (1.0 + c) - 1.0) * 1e6;
    }
  }
  void contribute(const Recording& r, Contribution& out) const override {
    for (int a = 0; a < 2; ++a) {
      const double c = 1.0 / (1.0 + ppm_[a] * 1e-6) - 1.0;
      for (size_t i = 0; i < r.n; ++i) out.v[a][i] = c * r.ref[a][i];
    }
  }
  ojson params() const override { return per_axis_params("ppm", ppm_); }
  void set(const EffectParams& p) override { set_per_axis(p, "ppm", ppm_); }
  int columns() const override { return 2; }  // the reference, one per axis
  void column_values(const Recording& r, size_t i, int a, double* v) const override {
    own_axis_columns(a, r.ref[a][i], v);
  }
  void set_linear(const std::vector<double>& w) override {
    for (int a = 0; a < 2; ++a) ppm_[a] = (1.0 / (1.0 + w[a]) - 1.0) * 1e6;
  }

 private:
  double ppm_[2] = {0, 0};
};

// ------------------------------------------------------------------ boresight_roll
// Sensor pitch = p cos phi - y sin phi, sensor yaw = p sin phi + y cos phi.
class BoresightRoll : public NamedCandidate<BoresightRoll> {
 public:
  BoresightRoll() : NamedCandidate("boresight_roll", 1) {}
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    // Rotation that best maps x = (p, y) onto u = x + target (Procrustes, exact).
    double sc = 0, ss = 0;
    for (uint32_t i : rows) {
      const double p = r.ref[0][i], y = r.ref[1][i];
      const double up = p + tg.v[0][i], uy = y + tg.v[1][i];
      sc += up * p + uy * y;
      ss += uy * p - up * y;
    }
    phi_ = std::atan2(ss, sc);
  }
  void contribute(const Recording& r, Contribution& out) const override {
    const double c = std::cos(phi_), s = std::sin(phi_);
    for (size_t i = 0; i < r.n; ++i) {
      const double p = r.ref[0][i], y = r.ref[1][i];
      out.v[0][i] = p * c - y * s - p;
      out.v[1][i] = p * s + y * c - y;
    }
  }
  ojson params() const override { return {{"roll_arcsec", rad_to_arcsec(phi_)}}; }
  void set(const EffectParams& p) override { phi_ = arcsec_to_rad(get(p, "roll_arcsec")); }
  // Linear in sin(phi) once cos(phi) - 1 (below 1e-5 of the angle for rolls under 15 arcmin) is left out.
  int columns() const override { return 1; }
  void column_values(const Recording& r, size_t i, int a, double* v) const override {
    v[0] = a == 0 ? -r.ref[1][i] : r.ref[0][i];
  }
  void set_linear(const std::vector<double>& w) override { phi_ = std::asin(std::clamp(w[0], -1.0, 1.0)); }

 private:
  double phi_ = 0;
};

// ------------------------------------------------------------------ axis_nonorthogonality
// Sensor yaw = y + sin(skew) p; pitch untouched.
class AxisNonorthogonality : public NamedCandidate<AxisNonorthogonality> {
 public:
  AxisNonorthogonality() : NamedCandidate("axis_nonorthogonality", 1) {}
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    s_ = std::clamp(slope(rows, tg.v[1], [&](uint32_t i) { return r.ref[0][i]; }), -1.0, 1.0);
  }
  void contribute(const Recording& r, Contribution& out) const override {
    std::fill(out.v[0].begin(), out.v[0].end(), 0.0);
    for (size_t i = 0; i < r.n; ++i) out.v[1][i] = s_ * r.ref[0][i];
  }
  ojson params() const override { return {{"skew_arcsec", rad_to_arcsec(std::asin(s_))}}; }
  void set(const EffectParams& p) override { s_ = std::sin(arcsec_to_rad(get(p, "skew_arcsec"))); }
  int columns() const override { return 1; }  // pitch, on yaw only
  void column_values(const Recording& r, size_t i, int a, double* v) const override {
    v[0] = a == 1 ? r.ref[0][i] : 0.0;
  }
  void set_linear(const std::vector<double>& w) override { s_ = std::clamp(w[0], -1.0, 1.0); }

 private:
  double s_ = 0;  // sin(skew)
};

// ------------------------------------------------------------------ backlash
// Each axis's true position lags the encoder by width/2 against its last motion.
class Backlash : public NamedCandidate<Backlash> {
 public:
  Backlash() : NamedCandidate("backlash", 1) {}
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    double sxy = 0, sxx = 0;
    for (int a = 0; a < 2; ++a) {
      for (uint32_t i : rows) {
        const double d = r.dir[a][i];
        sxy += -0.5 * d * tg.v[a][i];
        sxx += 0.25 * d * d;
      }
    }
    w_ = ratio(sxy, sxx);
  }
  void contribute(const Recording& r, Contribution& out) const override {
    for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) out.v[a][i] = -0.5 * r.dir[a][i] * w_;
  }
  ojson params() const override { return {{"width_arcsec", w_}}; }
  void set(const EffectParams& p) override { w_ = get(p, "width_arcsec"); }
  int columns() const override { return 1; }
  void column_values(const Recording& r, size_t i, int a, double* v) const override { v[0] = -0.5 * r.dir[a][i]; }
  void set_linear(const std::vector<double>& w) override { w_ = w[0]; }

 private:
  double w_ = 0;
};

// ------------------------------------------------------------------ settling
// After each move the true position is the target + amplitude exp(-(t - t_arrival)/tau) in the
// direction of the move; nothing while moving.
class Settling : public NamedCandidate<Settling> {
  static constexpr double kMaxTau = 30.0;  // s

 public:
  Settling() : NamedCandidate("settling", 2) {}
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    // tau profiled on a log grid (the amplitude is linear), then golden section.
    auto solve = [&](double log_tau, double* amp) {
      const double tau = std::exp(log_tau);
      double sxy = 0, sxx = 0, syy = 0;
      for (uint32_t i : rows) {
        const double tm = r.since_move[i];
        if (!std::isfinite(tm) || tm < 0) continue;
        const double e = std::exp(-tm / tau);
        for (int a = 0; a < 2; ++a) {
          const double g = r.move_dir[a][i] * e;
          sxy += g * tg.v[a][i];
          sxx += g * g;
          syy += tg.v[a][i] * tg.v[a][i];
        }
      }
      const double A = ratio(sxy, sxx);
      if (amp) *amp = A;
      return syy - A * sxy;
    };
    const double lt = minimise_1d([&](double x) { return solve(x, nullptr); }, std::log(0.02), std::log(kMaxTau), 60, 1e-4);
    tau_ = std::exp(lt);
    solve(lt, &amp_);
  }
  void contribute(const Recording& r, Contribution& out) const override {
    for (size_t i = 0; i < r.n; ++i) {
      const double e = amp_ * decay(r, i);
      for (int a = 0; a < 2; ++a) out.v[a][i] = r.move_dir[a][i] * e;
    }
  }
  ojson params() const override { return {{"amplitude_arcsec", amp_}, {"tau_s", tau_}}; }
  ojson notes() const override {
    if (tau_ < 0.99 * kMaxTau) return ojson::object();
    return {{"tau_s", "at the search limit: the dwells do not resolve a decay"}};
  }
  void set(const EffectParams& p) override { amp_ = get(p, "amplitude_arcsec"); tau_ = get(p, "tau_s"); }
  int columns() const override { return 1; }  // the decay of unit amplitude at this tau
  void column_values(const Recording& r, size_t i, int a, double* v) const override { v[0] = r.move_dir[a][i] * decay(r, i); }
  void set_linear(const std::vector<double>& w) override { amp_ = w[0]; }

 private:
  // exp(-t_since/tau) at row i, 0 where no arrival rings.
  double decay(const Recording& r, size_t i) const {
    const double tm = r.since_move[i];
    return std::isfinite(tm) && tm >= 0 && tau_ > 0 ? std::exp(-tm / tau_) : 0.0;
  }

  double amp_ = 0, tau_ = 1;
};

// ------------------------------------------------------------------ time_skew
// The sensor's sample at time t shows the Sun at t - skew_s: within a slew segment the sensor
// sees the reference interpolated at t - skew; at rest it sees the same as the reference.
class TimeSkew : public NamedCandidate<TimeSkew> {
 public:
  TimeSkew() : NamedCandidate("time_skew", 1) {}
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    std::vector<uint32_t> moving, coarse;
    for (uint32_t i : rows) if (r.steps[r.step_of[i]].kind == StepKind::motion) moving.push_back(i);
    // The grid stage (it only has to land in the right valley) sees at most ~4000 rows.
    const size_t stride = std::max<size_t>(1, moving.size() / 4000);
    for (size_t k = 0; k < moving.size(); k += stride) coarse.push_back(moving[k]);
    const std::vector<StepRows> all_steps = by_step(r, moving), coarse_steps = by_step(r, coarse);
    const double lim = r.guard_s;
    if (!(lim > 0) || moving.empty()) { skew_ = 0; return; }
    constexpr double kStep = 0.004;  // s; the reference is sampled every 20 ms or more
    const int steps = std::max(20, static_cast<int>(std::ceil(2 * lim / kStep)));
    double best = -lim, best_c = std::numeric_limits<double>::infinity();
    for (int k = 0; k <= steps; ++k) {
      const double sk = -lim + 2 * lim * k / steps, c = cost(r, tg, coarse_steps, sk);
      if (c < best_c) { best_c = c; best = sk; }
    }
    const double d = 2 * lim / steps;
    skew_ = minimise_1d([&](double sk) { return cost(r, tg, all_steps, sk); }, std::max(-lim, best - 2 * d),
                        std::min(lim, best + 2 * d), 8, 1e-6);
  }
  void contribute(const Recording& r, Contribution& out) const override {
    out.resize(r.n);
    for (const Step& st : r.steps) {
      if (st.kind != StepKind::motion) continue;
      size_t j = st.begin;
      for (size_t i = st.begin; i < st.end; ++i) {
        double p[2];
        shown(r, st, r.t[i] - skew_, j, p);
        for (int a = 0; a < 2; ++a) out.v[a][i] = st.moves[a] ? p[a] - r.ref[a][i] : 0.0;
      }
    }
  }
  ojson params() const override { return {{"skew_s", skew_}}; }
  void set(const EffectParams& p) override { skew_ = get(p, "skew_s"); }

 private:
  // The reference of step `st` at time tq (both axes): linear between its samples, held at its
  // ends. `j` is where the search for the segment starts (the one found last, or a guess); the
  // segment found, the last sample at or before tq, is the same from any start.
  static void shown(const Recording& r, const Step& st, double tq, size_t& j, double* p) {
    const auto& t = r.t;
    if (st.end - st.begin < 2 || tq <= t[st.begin]) {
      for (int a = 0; a < 2; ++a) p[a] = r.ref[a][st.begin];
      return;
    }
    if (tq >= t[st.end - 1]) {
      for (int a = 0; a < 2; ++a) p[a] = r.ref[a][st.end - 1];
      return;
    }
    j = std::clamp(j, st.begin, st.end - 2);
    while (j > st.begin && t[j] > tq) --j;
    while (j + 2 < st.end && t[j + 1] <= tq) ++j;
    const double dt = t[j + 1] - t[j];
    const double w = dt > 0 ? (tq - t[j]) / dt : 0.0;
    for (int a = 0; a < 2; ++a) p[a] = r.ref[a][j] + w * (r.ref[a][j + 1] - r.ref[a][j]);
  }

  // The rows of one slew segment that a cost sums, in time order (the segment looked up once).
  struct StepRows {
    const Step* step;
    std::vector<uint32_t> rows;
  };
  static std::vector<StepRows> by_step(const Recording& r, const std::vector<uint32_t>& rows) {
    std::vector<StepRows> out;
    for (uint32_t i : rows) {
      const Step* st = &r.steps[r.step_of[i]];
      if (out.empty() || out.back().step != st) out.push_back({st, {}});
      out.back().rows.push_back(i);
    }
    return out;
  }
  // Sum over the rows and both axes of (target - what a skew s adds)^2.
  static double cost(const Recording& r, const Contribution& tg, const std::vector<StepRows>& steps, double s) {
    double c = 0;
    for (const StepRows& sr : steps) {
      const Step& st = *sr.step;
      // The segment of the row before, moved on by as many rows (times never decrease, so the
      // search ends where it would from the segment's start, a step or two away).
      size_t j = st.begin, prev = st.begin;
      for (uint32_t i : sr.rows) {
        j += i - prev;
        prev = i;
        double p[2];
        shown(r, st, r.t[i] - s, j, p);
        for (int a = 0; a < 2; ++a) {
          const double e = tg.v[a][i] - (st.moves[a] ? p[a] - r.ref[a][i] : 0.0);
          c += e * e;
        }
      }
    }
    return c;
  }

  double skew_ = 0;
};

// ------------------------------------------------------------------ temperature
// The sensor sees p + k (T - T0) on each axis; T0 (the profile's t0_c) is fitted too.
class Temperature : public NamedCandidate<Temperature> {
 public:
  Temperature() : NamedCandidate("temperature", 3) {}
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    // Sums so that the cost at any T0 is closed-form: sum (tg - k (T - T0))^2 with k optimal.
    double n = 0, sT = 0, sTT = 0, sy[2] = {0, 0}, sTy[2] = {0, 0}, syy[2] = {0, 0};
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (uint32_t i : rows) {
      const double T = r.temp[i];
      if (!std::isfinite(T)) continue;
      n += 1; sT += T; sTT += T * T;
      lo = std::min(lo, T); hi = std::max(hi, T);
      for (int a = 0; a < 2; ++a) { sy[a] += tg.v[a][i]; sTy[a] += T * tg.v[a][i]; syy[a] += tg.v[a][i] * tg.v[a][i]; }
    }
    if (n == 0) { k_[0] = k_[1] = 0; return; }
    auto cost = [&](double T0, double* k) {
      const double dd = sTT - 2 * T0 * sT + T0 * T0 * n;
      double c = 0;
      for (int a = 0; a < 2; ++a) {
        const double dy = sTy[a] - T0 * sy[a];
        const double ka = ratio(dy, dd);
        if (k) k[a] = ka;
        c += syy[a] - ka * dy;
      }
      return c;
    };
    const double span = std::max(hi - lo, 0.1);
    if (!held_) t0_ = minimise_1d([&](double T0) { return cost(T0, nullptr); }, lo - 20 * span, hi + 20 * span, 800, 1e-7 * span);
    cost(t0_, k_);
  }
  void contribute(const Recording& r, Contribution& out) const override {
    for (size_t i = 0; i < r.n; ++i) {
      const double d = std::isfinite(r.temp[i]) ? r.temp[i] - t0_ : 0.0;
      for (int a = 0; a < 2; ++a) out.v[a][i] = k_[a] * d;
    }
  }
  ojson params() const override {
    ojson j = per_axis_params("arcsec_per_c", k_);
    j["t0_c"] = t0_;
    return j;
  }
  void set(const EffectParams& p) override {
    set_per_axis(p, "arcsec_per_c", k_);
    t0_ = p.params.count("t0_c") ? p.params.at("t0_c") : 20.0;
  }
  int columns() const override { return 2; }  // T - T0, one per axis
  void column_values(const Recording& r, size_t i, int a, double* v) const override {
    const double d = std::isfinite(r.temp[i]) ? r.temp[i] - t0_ : 0.0;
    own_axis_columns(a, d, v);
  }
  void set_linear(const std::vector<double>& w) override { k_[0] = w[0]; k_[1] = w[1]; }
  void hold(const std::string& key, double value) override {
    if (key == "t0_c") { t0_ = value; held_ = true; }
  }
  ojson notes() const override {
    if (!held_) return ojson::object();
    return {{"t0_c", "held at the recording's first temperature reading: with a constant offset also fitted (bias, "
                     "or a refitted C1), the temperature at which the effect vanishes cannot be told apart from it"}};
  }

 private:
  double k_[2] = {0, 0}, t0_ = 20.0;
  bool held_ = false;
};

}  // namespace

std::unique_ptr<Candidate> make_candidate(const std::string& name) {
  if (name == "bias") return std::make_unique<Bias>();
  if (name == "drift") return std::make_unique<Drift>();
  if (name == "scale_factor") return std::make_unique<ScaleFactor>();
  if (name == "boresight_roll") return std::make_unique<BoresightRoll>();
  if (name == "axis_nonorthogonality") return std::make_unique<AxisNonorthogonality>();
  if (name == "backlash") return std::make_unique<Backlash>();
  if (name == "settling") return std::make_unique<Settling>();
  if (name == "time_skew") return std::make_unique<TimeSkew>();
  if (name == "coefficients") return make_coefficients_candidate();
  if (name == "temperature") return std::make_unique<Temperature>();
  return nullptr;
}

}  // namespace fpss::diag
