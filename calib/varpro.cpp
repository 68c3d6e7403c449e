#include "calib/varpro.h"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "calib/residuals.h"
#include "calib/units.h"

namespace fpss::fit {
namespace {
constexpr int kChunk = 256;
const double kNominalC2Arcsec = kNominalC2 * kArcsecPerRad;

// Writes the features of one count value from column `base` on: sin/cos of w_j N for all j,
// by rotation from the first frequency (exact to ~1e-14 over a few hundred steps, and one
// sincos per count instead of one per frequency).
void add_trig(double n, double w0, double dw, size_t freqs, double sign, double* out) {
  double s = std::sin(w0 * n), c = std::cos(w0 * n);
  const double sd = std::sin(dw * n), cd = std::cos(dw * n);
  for (size_t j = 0; j < freqs; ++j) {
    out[2 * j] += sign * s;
    out[2 * j + 1] += sign * c;
    const double s2 = s * cd + c * sd;
    c = c * cd - s * sd;
    s = s2;
  }
}
}  // namespace

FrequencyGram::FrequencyGram(const GridConfig& grid, bool differences)
    : grid_(grid), differences_(differences) {
  if (!(grid.w_min > 0 && grid.w_step > 0 && grid.w_max > grid.w_min)) {
    throw std::invalid_argument("frequency grid needs 0 < w_min < w_max and w_step > 0");
  }
  freqs_ = static_cast<size_t>(std::floor((grid.w_max - grid.w_min) / grid.w_step + 1e-9)) + 1;
  base_ = differences ? 2 : 3;
  dim_ = base_ + 2 * static_cast<int>(freqs_);
  gram_ = Eigen::MatrixXd::Zero(dim_, dim_);
  chunk_.resize(dim_, kChunk);
}

void FrequencyGram::add(const double* n_plus, const double* n_minus, const double* y, size_t count) {
  for (size_t i = 0; i < count; ++i) {
    double* col = chunk_.col(static_cast<Eigen::Index>(pending_)).data();
    std::fill(col, col + dim_, 0.0);
    const double dn = differences_ ? n_plus[i] - n_minus[i] : n_plus[i];
    col[0] = y[i] - kNominalC2Arcsec * dn;
    col[1] = dn / kCountScale;
    if (!differences_) col[2] = 1.0;
    add_trig(n_plus[i], grid_.w_min, grid_.w_step, freqs_, 1.0, col + base_);
    if (differences_) add_trig(n_minus[i], grid_.w_min, grid_.w_step, freqs_, -1.0, col + base_);
    ++rows_;
    if (++pending_ == kChunk) flush();
  }
}

void FrequencyGram::flush() const {
  if (pending_ == 0) return;
  gram_.selfadjointView<Eigen::Lower>().rankUpdate(chunk_.leftCols(static_cast<Eigen::Index>(pending_)));
  pending_ = 0;
}

FrequencyGram::Node FrequencyGram::solve(int j, int k) const {
  flush();
  Node node;
  const int p = base_ - 1 + 4;  // slope [, constant], two sin/cos pairs
  if (rows_ < static_cast<size_t>(p) + 1) return node;
  int idx[6];
  int m = 0;
  for (int c = 1; c < base_; ++c) idx[m++] = c;
  idx[m++] = base_ + 2 * j;
  idx[m++] = base_ + 2 * j + 1;
  idx[m++] = base_ + 2 * k;
  idx[m++] = base_ + 2 * k + 1;
  using Mat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;
  using Vec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1>;
  Mat a(p, p);
  Vec b(p), d(p);
  for (int r = 0; r < p; ++r) {
    const double diag = g(idx[r], idx[r]);
    if (!(diag > 0)) return node;
    d(r) = 1.0 / std::sqrt(diag);
  }
  // Equilibrated to a unit diagonal: the conditioning left is the features' true collinearity.
  for (int r = 0; r < p; ++r) {
    b(r) = g(idx[r], 0) * d(r);
    for (int c = 0; c < p; ++c) a(r, c) = g(idx[r], idx[c]) * d(r) * d(c);
  }
  Eigen::LDLT<Mat> ldlt(a);
  if (ldlt.info() != Eigen::Success) return node;
  const auto piv = ldlt.vectorD().cwiseAbs();
  if (!(piv.minCoeff() > 1e-12 * piv.maxCoeff())) return node;
  const Vec xs = ldlt.solve(b);
  node.j = j;
  node.k = k;
  node.cost = std::max(0.0, g(0, 0) - b.dot(xs));
  for (int r = 0; r < p; ++r) node.x[r] = xs(r) * d(r);
  return node;
}

std::vector<FrequencyGram::Node> FrequencyGram::best_nodes(size_t max_count) const {
  const int n = static_cast<int>(freqs_);
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<Node> grid(static_cast<size_t>(n) * n);
  auto at = [&](int j, int k) -> Node& { return grid[static_cast<size_t>(j) * n + k]; };
  for (int j = 0; j < n; ++j) {
    for (int k = j + grid_.min_separation_steps; k < n; ++k) at(j, k) = solve(j, k);
  }
  std::vector<Node> minima;
  for (int j = 0; j < n; ++j) {
    for (int k = j + 1; k < n; ++k) {
      const Node& c = at(j, k);
      if (!c.valid()) continue;
      bool is_min = true;
      for (int dj = -1; dj <= 1 && is_min; ++dj) {
        for (int dk = -1; dk <= 1; ++dk) {
          const int jj = j + dj, kk = k + dk;
          if ((dj == 0 && dk == 0) || jj < 0 || kk >= n || jj >= kk) continue;
          const double nc = at(jj, kk).valid() ? at(jj, kk).cost : inf;
          // Ties go to the lexicographically first node so a plateau yields one minimum.
          if (nc < c.cost || (nc == c.cost && (jj < j || (jj == j && kk < k)))) { is_min = false; break; }
        }
      }
      if (is_min) minima.push_back(c);
    }
  }
  std::sort(minima.begin(), minima.end(), [](const Node& a, const Node& b) { return a.cost < b.cost; });
  if (minima.size() > max_count) minima.resize(max_count);
  return minima;
}

AxisCoeffs FrequencyGram::coefficients(const Node& node) const {
  AxisCoeffs c{};
  const double* x = node.x.data();
  c[1] = kNominalC2 + x[0] / kCountScale / kArcsecPerRad;
  const double* ab = x + (base_ - 1);
  if (!differences_) c[0] = x[1] / kArcsecPerRad;
  c[2] = std::hypot(ab[0], ab[1]) / kArcsecPerRad;
  c[3] = frequency(static_cast<size_t>(node.j));
  c[4] = std::atan2(ab[1], ab[0]);
  c[5] = std::hypot(ab[2], ab[3]) / kArcsecPerRad;
  c[6] = frequency(static_cast<size_t>(node.k));
  c[7] = std::atan2(ab[3], ab[2]);
  return c;
}

}  // namespace fpss::fit
