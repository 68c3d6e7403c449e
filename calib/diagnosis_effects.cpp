// The candidate effects: each one's forward model (the emulator's convention, fixtures/bench.cpp)
// and its least-squares fit on the fit rows. Residual = model(counts) - reference, arcsec.
#include <ceres/ceres.h>
#include <fmt/format.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "calib/diagnosis_model.h"
#include "calib/units.h"

namespace fpss::diag {
namespace {

using Rows = std::vector<uint32_t>;
using ojson = nlohmann::ordered_json;

double get(const EffectParams& p, const char* key) {
  auto it = p.params.find(key);
  return it == p.params.end() ? 0.0 : it->second;
}

// Least squares of one scale factor: target ~ c * x over rows, both axes pooled when asked.
double ratio(double sxy, double sxx) { return sxx > 0 ? sxy / sxx : 0.0; }

// A column with values on one axis only (the other zero).
Contribution axis_column(const Recording& r, int axis, const std::vector<double>& v) {
  Contribution c;
  c.resize(r.n);
  c.v[axis] = v;
  return c;
}

// ------------------------------------------------------------------ bias
class Bias : public Candidate {
 public:
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<Bias>(*this); }
  std::string name() const override { return "bias"; }
  int parameters() const override { return 2; }
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    for (int a = 0; a < 2; ++a) {
      double s = 0;
      for (uint32_t i : rows) s += tg.v[a][i];
      b_[a] = rows.empty() ? 0.0 : s / static_cast<double>(rows.size());
    }
  }
  void contribute(const Recording& r, Contribution& out) const override {
    for (int a = 0; a < 2; ++a) std::fill(out.v[a].begin(), out.v[a].end(), b_[a]);
  }
  ojson params() const override { return {{"pitch_arcsec", b_[0]}, {"yaw_arcsec", b_[1]}}; }
  void set(const EffectParams& p) override { b_[0] = get(p, "pitch_arcsec"); b_[1] = get(p, "yaw_arcsec"); }
  bool columns(const Recording& r, std::vector<Contribution>& cols) const override {
    const std::vector<double> one(r.n, 1.0);
    cols = {axis_column(r, 0, one), axis_column(r, 1, one)};
    return true;
  }
  void set_linear(const std::vector<double>& w) override { b_[0] = w[0]; b_[1] = w[1]; }

 private:
  double b_[2] = {0, 0};
};

// ------------------------------------------------------------------ drift: rate * t (bench time)
class Drift : public Candidate {
 public:
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<Drift>(*this); }
  std::string name() const override { return "drift"; }
  int parameters() const override { return 2; }
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    for (int a = 0; a < 2; ++a) {
      double sxy = 0, sxx = 0;
      for (uint32_t i : rows) { sxy += r.t[i] * tg.v[a][i]; sxx += r.t[i] * r.t[i]; }
      k_[a] = ratio(sxy, sxx);
    }
  }
  void contribute(const Recording& r, Contribution& out) const override {
    for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) out.v[a][i] = k_[a] * r.t[i];
  }
  ojson params() const override { return {{"pitch_arcsec_per_s", k_[0]}, {"yaw_arcsec_per_s", k_[1]}}; }
  void set(const EffectParams& p) override {
    k_[0] = get(p, "pitch_arcsec_per_s");
    k_[1] = get(p, "yaw_arcsec_per_s");
  }
  bool columns(const Recording& r, std::vector<Contribution>& cols) const override {
    cols = {axis_column(r, 0, r.t), axis_column(r, 1, r.t)};
    return true;
  }
  void set_linear(const std::vector<double>& w) override { k_[0] = w[0]; k_[1] = w[1]; }

 private:
  double k_[2] = {0, 0};
};

// ------------------------------------------------------------------ scale_factor
// The gimbal reads (1 + ppm 1e-6) x the true angle: the sensor sees ref / (1 + ppm 1e-6).
class ScaleFactor : public Candidate {
 public:
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<ScaleFactor>(*this); }
  std::string name() const override { return "scale_factor"; }
  int parameters() const override { return 2; }
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    for (int a = 0; a < 2; ++a) {
      double sxy = 0, sxx = 0;
      for (uint32_t i : rows) { sxy += r.ref[a][i] * tg.v[a][i]; sxx += r.ref[a][i] * r.ref[a][i]; }
      const double c = ratio(sxy, sxx);  // residual = c * ref, c = 1/(1+k) - 1
      ppm_[a] = (1.0 / (1.0 + c) - 1.0) * 1e6;
    }
  }
  void contribute(const Recording& r, Contribution& out) const override {
    for (int a = 0; a < 2; ++a) {
      const double c = 1.0 / (1.0 + ppm_[a] * 1e-6) - 1.0;
      for (size_t i = 0; i < r.n; ++i) out.v[a][i] = c * r.ref[a][i];
    }
  }
  ojson params() const override { return {{"pitch_ppm", ppm_[0]}, {"yaw_ppm", ppm_[1]}}; }
  void set(const EffectParams& p) override { ppm_[0] = get(p, "pitch_ppm"); ppm_[1] = get(p, "yaw_ppm"); }
  bool columns(const Recording& r, std::vector<Contribution>& cols) const override {
    cols = {axis_column(r, 0, r.ref[0]), axis_column(r, 1, r.ref[1])};
    return true;
  }
  void set_linear(const std::vector<double>& w) override {
    for (int a = 0; a < 2; ++a) ppm_[a] = (1.0 / (1.0 + w[a]) - 1.0) * 1e6;
  }

 private:
  double ppm_[2] = {0, 0};
};

// ------------------------------------------------------------------ boresight_roll
// Sensor pitch = p cos phi - y sin phi, sensor yaw = p sin phi + y cos phi.
class BoresightRoll : public Candidate {
 public:
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<BoresightRoll>(*this); }
  std::string name() const override { return "boresight_roll"; }
  int parameters() const override { return 1; }
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
  bool columns(const Recording& r, std::vector<Contribution>& cols) const override {
    Contribution c;
    c.resize(r.n);
    for (size_t i = 0; i < r.n; ++i) { c.v[0][i] = -r.ref[1][i]; c.v[1][i] = r.ref[0][i]; }
    cols = {c};
    return true;
  }
  void set_linear(const std::vector<double>& w) override { phi_ = std::asin(std::clamp(w[0], -1.0, 1.0)); }

 private:
  double phi_ = 0;
};

// ------------------------------------------------------------------ axis_nonorthogonality
// Sensor yaw = y + sin(skew) p; pitch untouched.
class AxisNonorthogonality : public Candidate {
 public:
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<AxisNonorthogonality>(*this); }
  std::string name() const override { return "axis_nonorthogonality"; }
  int parameters() const override { return 1; }
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    double sxy = 0, sxx = 0;
    for (uint32_t i : rows) { sxy += r.ref[0][i] * tg.v[1][i]; sxx += r.ref[0][i] * r.ref[0][i]; }
    s_ = std::clamp(ratio(sxy, sxx), -1.0, 1.0);
  }
  void contribute(const Recording& r, Contribution& out) const override {
    std::fill(out.v[0].begin(), out.v[0].end(), 0.0);
    for (size_t i = 0; i < r.n; ++i) out.v[1][i] = s_ * r.ref[0][i];
  }
  ojson params() const override { return {{"skew_arcsec", rad_to_arcsec(std::asin(s_))}}; }
  void set(const EffectParams& p) override { s_ = std::sin(arcsec_to_rad(get(p, "skew_arcsec"))); }
  bool columns(const Recording& r, std::vector<Contribution>& cols) const override {
    cols = {axis_column(r, 1, r.ref[0])};
    return true;
  }
  void set_linear(const std::vector<double>& w) override { s_ = std::clamp(w[0], -1.0, 1.0); }

 private:
  double s_ = 0;  // sin(skew)
};

// ------------------------------------------------------------------ backlash
// Each axis's true position lags the encoder by width/2 against its last motion.
class Backlash : public Candidate {
 public:
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<Backlash>(*this); }
  std::string name() const override { return "backlash"; }
  int parameters() const override { return 1; }
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
  bool columns(const Recording& r, std::vector<Contribution>& cols) const override {
    Contribution c;
    c.resize(r.n);
    for (int a = 0; a < 2; ++a) for (size_t i = 0; i < r.n; ++i) c.v[a][i] = -0.5 * r.dir[a][i];
    cols = {c};
    return true;
  }
  void set_linear(const std::vector<double>& w) override { w_ = w[0]; }

 private:
  double w_ = 0;
};

// ------------------------------------------------------------------ settling
// After each move the true position is the target + amplitude exp(-(t - t_arrival)/tau) in the
// direction of the move; nothing while moving.
class Settling : public Candidate {
  static constexpr double kMaxTau = 30.0;  // s

 public:
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<Settling>(*this); }
  std::string name() const override { return "settling"; }
  int parameters() const override { return 2; }
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
      const double tm = r.since_move[i];
      const double e = std::isfinite(tm) && tm >= 0 && tau_ > 0 ? amp_ * std::exp(-tm / tau_) : 0.0;
      for (int a = 0; a < 2; ++a) out.v[a][i] = r.move_dir[a][i] * e;
    }
  }
  ojson params() const override { return {{"amplitude_arcsec", amp_}, {"tau_s", tau_}}; }
  ojson notes() const override {
    if (tau_ < 0.99 * kMaxTau) return ojson::object();
    return {{"tau_s", "at the search limit: the dwells do not resolve a decay"}};
  }
  void set(const EffectParams& p) override { amp_ = get(p, "amplitude_arcsec"); tau_ = get(p, "tau_s"); }
  bool columns(const Recording& r, std::vector<Contribution>& cols) const override {
    Settling unit = *this;
    unit.amp_ = 1.0;
    Contribution c;
    c.resize(r.n);
    unit.contribute(r, c);
    cols = {c};
    return true;
  }
  void set_linear(const std::vector<double>& w) override { amp_ = w[0]; }

 private:
  double amp_ = 0, tau_ = 1;
};

// ------------------------------------------------------------------ time_skew
// The sensor's sample at time t shows the Sun at t - skew_s: within a slew segment the sensor
// sees the reference interpolated at t - skew; at rest it sees the same as the reference.
class TimeSkew : public Candidate {
 public:
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<TimeSkew>(*this); }
  std::string name() const override { return "time_skew"; }
  int parameters() const override { return 1; }
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    std::vector<uint32_t> moving, coarse;
    for (uint32_t i : rows) if (r.steps[r.step_of[i]].kind == StepKind::motion) moving.push_back(i);
    // The grid stage (it only has to land in the right valley) sees at most ~4000 rows.
    const size_t stride = std::max<size_t>(1, moving.size() / 4000);
    for (size_t k = 0; k < moving.size(); k += stride) coarse.push_back(moving[k]);
    auto cost = [&](const std::vector<uint32_t>& use, double s) {
      double c = 0;
      size_t j = 0;
      uint32_t cur = UINT32_MAX;
      for (uint32_t i : use) {
        const Step& st = r.steps[r.step_of[i]];
        if (r.step_of[i] != cur) { cur = r.step_of[i]; j = st.begin; }
        double p[2];
        shown(r, st, r.t[i] - s, j, p);
        for (int a = 0; a < 2; ++a) {
          const double e = tg.v[a][i] - (st.moves[a] ? p[a] - r.ref[a][i] : 0.0);
          c += e * e;
        }
      }
      return c;
    };
    const double lim = r.guard_s;
    if (!(lim > 0) || moving.empty()) { skew_ = 0; return; }
    constexpr double kStep = 0.004;  // s; the reference is sampled every 20 ms or more
    const int steps = std::max(20, static_cast<int>(std::ceil(2 * lim / kStep)));
    double best = -lim, best_c = std::numeric_limits<double>::infinity();
    for (int k = 0; k <= steps; ++k) {
      const double sk = -lim + 2 * lim * k / steps, c = cost(coarse, sk);
      if (c < best_c) { best_c = c; best = sk; }
    }
    const double d = 2 * lim / steps;
    skew_ = minimise_1d([&](double sk) { return cost(moving, sk); }, std::max(-lim, best - 2 * d), std::min(lim, best + 2 * d), 8, 1e-6);
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
  // ends. `j` is the segment found last; queries come in time order, so it only moves forward.
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

  double skew_ = 0;
};

// ------------------------------------------------------------------ temperature
// The sensor sees p + k (T - T0) on each axis; T0 (the profile's t0_c) is fitted too.
class Temperature : public Candidate {
 public:
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<Temperature>(*this); }
  std::string name() const override { return "temperature"; }
  int parameters() const override { return 3; }
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
    return {{"pitch_arcsec_per_c", k_[0]}, {"yaw_arcsec_per_c", k_[1]}, {"t0_c", t0_}};
  }
  void set(const EffectParams& p) override {
    k_[0] = get(p, "pitch_arcsec_per_c");
    k_[1] = get(p, "yaw_arcsec_per_c");
    t0_ = p.params.count("t0_c") ? p.params.at("t0_c") : 20.0;
  }
  bool columns(const Recording& r, std::vector<Contribution>& cols) const override {
    std::vector<double> d(r.n);
    for (size_t i = 0; i < r.n; ++i) d[i] = std::isfinite(r.temp[i]) ? r.temp[i] - t0_ : 0.0;
    cols = {axis_column(r, 0, d), axis_column(r, 1, d)};
    return true;
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

// ------------------------------------------------------------------ coefficients
// The sensor's transfer function differs from the model's: eq. 1 refitted per axis to what the
// residual says the angle at each count is. Scaled parameters keep the Jacobian balanced.
constexpr double kS = 16384.0;  // counts over half the field

struct Eq1Arcsec {  // u: C1 arcsec, C2 arcsec per kS counts, C3 arcsec, C4 rad per kS counts, C5, C6, C7, C8
  template <typename T>
  static T eval(const T* u, double n) {
    using std::sin;
    const double x = n / kS;
    return u[0] + u[1] * x + u[2] * sin(u[3] * x + u[4]) + u[5] * sin(u[6] * x + u[7]);
  }
};

struct Eq1Residuals {
  const double* n;
  const double* y;
  int count;
  template <typename T>
  bool operator()(const T* u, T* out) const {
    for (int i = 0; i < count; ++i) out[i] = Eq1Arcsec::eval(u, n[i]) - y[i];
    return true;
  }
};

std::array<double, 8> to_u(const AxisCoeffs& c) {
  return {rad_to_arcsec(c[0]), rad_to_arcsec(c[1]) * kS, rad_to_arcsec(c[2]), c[3] * kS, c[4],
          rad_to_arcsec(c[5]), c[6] * kS, c[7]};
}
AxisCoeffs from_u(const std::array<double, 8>& u) {
  return {arcsec_to_rad(u[0]), arcsec_to_rad(u[1]) / kS, arcsec_to_rad(u[2]), u[3] / kS, u[4],
          arcsec_to_rad(u[5]), u[6] / kS, u[7]};
}

double cost_of(const std::array<double, 8>& u, const std::vector<double>& n, const std::vector<double>& y) {
  double c = 0;
  for (size_t i = 0; i < n.size(); ++i) {
    const double e = Eq1Arcsec::eval(u.data(), n[i]) - y[i];
    c += e * e;
  }
  return c;
}

void refine(std::array<double, 8>& u, const std::vector<double>& n, const std::vector<double>& y) {
  ceres::Problem problem;
  constexpr int kBlock = 256;
  for (size_t i = 0; i < n.size(); i += kBlock) {
    const int m = static_cast<int>(std::min<size_t>(kBlock, n.size() - i));
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Eq1Residuals, ceres::DYNAMIC, 8>(
                                 new Eq1Residuals{n.data() + i, y.data() + i, m}, m),
                             nullptr, u.data());
  }
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_QR;
  o.max_num_iterations = 100;
  o.logging_type = ceres::SILENT;
  o.minimizer_progress_to_stdout = false;
  o.function_tolerance = 1e-12;
  o.parameter_tolerance = 1e-12;
  ceres::Solver::Summary summary;
  ceres::Solve(o, &problem, &summary);
}

// Variable projection: a log grid over both sinusoid frequencies (0.4e-4 .. 8e-4 rad/count, the
// published sets' span and more) with the linear parameters solved exactly at every node from one
// Gram matrix, then Ceres from the best node and from the model itself.
AxisCoeffs refit_axis(const AxisCoeffs& model, const std::vector<double>& n, const std::vector<double>& y) {
  constexpr int kW = 24;
  std::vector<double> f(kW);
  for (int j = 0; j < kW; ++j) f[j] = 0.4e-4 * std::pow(20.0, j / (kW - 1.0)) * kS;
  const size_t stride = std::max<size_t>(1, n.size() / 4000);
  const int dim = 2 + 2 * kW;
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(dim, dim);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(dim);
  Eigen::VectorXd row(dim);
  double yy = 0;
  for (size_t i = 0; i < n.size(); i += stride) {
    const double x = n[i] / kS;
    row(0) = 1;
    row(1) = x;
    for (int j = 0; j < kW; ++j) {
      row(2 + 2 * j) = std::sin(f[j] * x);
      row(3 + 2 * j) = std::cos(f[j] * x);
    }
    G.selfadjointView<Eigen::Lower>().rankUpdate(row);
    b += row * y[i];
    yy += y[i] * y[i];
  }
  G = G.selfadjointView<Eigen::Lower>();
  double best = std::numeric_limits<double>::infinity();
  std::array<double, 8> best_u = to_u(model);
  for (int j = 0; j < kW; ++j) {
    for (int k = j + 2; k < kW; ++k) {
      const int idx[6] = {0, 1, 2 + 2 * j, 3 + 2 * j, 2 + 2 * k, 3 + 2 * k};
      Eigen::Matrix<double, 6, 6> g;
      Eigen::Matrix<double, 6, 1> v;
      for (int p = 0; p < 6; ++p) {
        v(p) = b(idx[p]);
        for (int q = 0; q < 6; ++q) g(p, q) = G(idx[p], idx[q]);
      }
      Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(g);
      if (ldlt.info() != Eigen::Success) continue;
      const Eigen::Matrix<double, 6, 1> xs = ldlt.solve(v);
      const double c = yy - xs.dot(v);
      if (c < best && std::isfinite(c)) {
        best = c;
        // a sin + b cos = hypot(a, b) sin(w x + atan2(b, a))
        best_u = {xs(0), xs(1), std::hypot(xs(2), xs(3)), f[j], std::atan2(xs(3), xs(2)),
                  std::hypot(xs(4), xs(5)), f[k], std::atan2(xs(5), xs(4))};
      }
    }
  }
  // The refinement sees at most ~6000 rows (evenly strided): eight coefficients are pinned
  // far below the noise by that many.
  const size_t rs = std::max<size_t>(1, n.size() / 6000);
  std::vector<double> nr, yr;
  for (size_t i = 0; i < n.size(); i += rs) { nr.push_back(n[i]); yr.push_back(y[i]); }
  std::array<double, 8> from_model = to_u(model);
  refine(best_u, nr, yr);
  refine(from_model, nr, yr);
  return from_u(cost_of(best_u, nr, yr) <= cost_of(from_model, nr, yr) ? best_u : from_model);
}

class Coefficients : public Candidate {
 public:
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<Coefficients>(*this); }
  std::string name() const override { return "coefficients"; }
  int parameters() const override { return 16; }
  void fit(const Recording& r, const Contribution& tg, const Rows& rows) override {
    const AxisCoeffs model[2] = {r.model.alpha, r.model.beta};
    for (int a = 0; a < 2; ++a) {
      model_amp_[a] = std::max(std::abs(rad_to_arcsec(model[a][2])), std::abs(rad_to_arcsec(model[a][5])));
      std::vector<double> n, y;
      n.reserve(rows.size());
      y.reserve(rows.size());
      for (uint32_t i : rows) {
        n.push_back(r.counts[a][i]);
        y.push_back(r.meas[a][i] - tg.v[a][i]);  // the angle the sensor's true function gives here
      }
      if (n.size() < 8) {
        c_[a] = model[a];
      } else if (fitted_) {
        // Refitted again (a joint fit with another effect): the last solution is a good start.
        const size_t rs = std::max<size_t>(1, n.size() / 6000);
        std::vector<double> nr, yr;
        for (size_t i = 0; i < n.size(); i += rs) { nr.push_back(n[i]); yr.push_back(y[i]); }
        std::array<double, 8> u = to_u(c_[a]);
        refine(u, nr, yr);
        c_[a] = from_u(u);
      } else {
        c_[a] = refit_axis(model[a], n, y);
      }
      const auto [lo, hi] = std::minmax_element(n.begin(), n.end());
      if (!n.empty()) { lo_[a] = *lo; hi_[a] = *hi; }
    }
    fitted_ = true;
  }
  void contribute(const Recording& r, Contribution& out) const override {
    const AxisCoeffs model[2] = {r.model.alpha, r.model.beta};
    for (int a = 0; a < 2; ++a) {
      for (size_t i = 0; i < r.n; ++i) {
        const double nn = r.counts[a][i];
        out.v[a][i] = rad_to_arcsec(transfer_angle(model[a].data(), nn) - transfer_angle(c_[a].data(), nn));
      }
    }
  }
  ojson params() const override { return {{"alpha", c_[0]}, {"beta", c_[1]}}; }
  void restart() override { fitted_ = false; }
  void set(const EffectParams& p) override {
    if (p.coefficients) { c_[0] = p.coefficients->alpha; c_[1] = p.coefficients->beta; }
  }
  // Ill-conditioned or implausible: sinusoids far beyond any the sensor family shows (10x the
  // model's largest, at least 200 arcsec), or two that nearly cancel (each more than 10x what the
  // pair adds up to over the counts fitted): the refit then stands in for something eq. 1 is not.
  std::string degenerate() const override {
    if (!fitted_) return {};
    const char* axis[2] = {"alpha", "beta"};
    for (int a = 0; a < 2; ++a) {
      const double a3 = std::abs(rad_to_arcsec(c_[a][2])), a6 = std::abs(rad_to_arcsec(c_[a][5]));
      const double big = std::max(a3, a6), limit = std::max(200.0, 10.0 * model_amp_[a]);
      if (big > limit) {
        return fmt::format("{}: sinusoid amplitudes {:.0f} and {:.0f} arcsec, beyond physical plausibility (> {:.0f})",
                           axis[a], a3, a6, limit);
      }
      double s2 = 0;
      constexpr int kSteps = 200;
      for (int k = 0; k <= kSteps; ++k) {
        const double nn = lo_[a] + (hi_[a] - lo_[a]) * k / kSteps;
        const double v = rad_to_arcsec(c_[a][2] * std::sin(c_[a][3] * nn + c_[a][4]) +
                                       c_[a][5] * std::sin(c_[a][6] * nn + c_[a][7]));
        s2 += v * v;
      }
      const double rms = std::sqrt(s2 / (kSteps + 1));
      if (big > 50.0 && std::min(a3, a6) > 10.0 * rms) {
        return fmt::format("{}: two nearly cancelling sinusoids ({:.0f} and {:.0f} arcsec, together {:.1f} arcsec RMS): "
                           "an ill-conditioned refit",
                           axis[a], a3, a6, rms);
      }
    }
    return {};
  }
  ojson notes() const override {
    if (!fitted_) return ojson::object();
    return {{"params", "the sensor's transfer function (paper eq. 1) refitted per axis on the fit rows: C1..C8, "
                       "radians and counts, as in a coefficient file (the emulator's coefficients effect)"},
            {"counts_range", {{"alpha", {lo_[0], hi_[0]}}, {"beta", {lo_[1], hi_[1]}}}}};
  }

 private:
  AxisCoeffs c_[2]{};
  double lo_[2] = {0, 0}, hi_[2] = {0, 0};
  double model_amp_[2] = {0, 0};
  bool fitted_ = false;
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
  if (name == "coefficients") return std::make_unique<Coefficients>();
  if (name == "temperature") return std::make_unique<Temperature>();
  return nullptr;
}

}  // namespace fpss::diag
