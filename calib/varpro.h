// The global initialisation: a grid over both sinusoid frequencies with the linear parameters
// solved exactly at every node (variable projection), from one Gram matrix of all features.
#pragma once
#include <array>
#include <cstddef>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "calib/transfer_function.h"

namespace fpss::fit {

struct GridConfig {
  // |frequency| range searched, rad/count. sin(-wN + p) = -sin(wN - p), so the sign of a
  // published frequency is absorbed by its amplitude and only |w| is searched.
  double w_min = 0.5e-4;
  double w_max = 7.0e-4;
  double w_step = 1.0e-5;
  // Nodes with frequencies closer than this many steps are skipped: the two sinusoids
  // are then one in disguise and their linear problem is singular.
  int min_separation_steps = 2;
};

// Accumulates G = [y' F]^T [y' F] over data rows, where F holds, per row, the linear feature
// (N / kCountScale), a constant (absolute method only) and sin/cos of w_j N for every grid
// frequency w_j (the difference offset - null for the differences method); y' is the reference
// minus the nominal scale factor times N, which keeps the cancellation in y'^T y' small.
// Adding a row is a rank-one update of G, so the same object is the batch grid stage and the
// streaming (information-form recursive) least squares: every node's exact LS is a tiny solve
// from sub-blocks of G, whatever the number of rows.
class FrequencyGram {
 public:
  FrequencyGram(const GridConfig& grid, bool differences);

  // n_minus is ignored (may be null) for the absolute method.
  void add(const double* n_plus, const double* n_minus, const double* y_arcsec, size_t count);
  void add(double n_plus, double n_minus, double y_arcsec) { add(&n_plus, &n_minus, &y_arcsec, 1); }

  size_t rows() const { return rows_; }
  size_t frequencies() const { return freqs_; }
  double frequency(size_t j) const { return grid_.w_min + grid_.w_step * static_cast<double>(j); }
  bool differences() const { return differences_; }

  struct Node {
    int j = -1, k = -1;  // frequency indices, j < k
    double cost = std::numeric_limits<double>::infinity();  // sum of squared residuals, arcsec^2
    // Linear parameters, arcsec: slope correction, [constant,] a_j, b_j, a_k, b_k with
    // a sin(wN) + b cos(wN) = C3 sin(wN + C5), C3 = hypot(a, b), C5 = atan2(b, a).
    std::array<double, 6> x{};
    bool valid() const { return j >= 0; }
  };

  // Exact linear least squares at one node; an invalid node when it is singular.
  Node solve(int j, int k) const;
  // The best local minima of the node grid (8-neighbourhood), lowest cost first.
  std::vector<Node> best_nodes(size_t max_count) const;
  // The coefficients of a node (C1 = 0 for the differences method).
  AxisCoeffs coefficients(const Node& node) const;

 private:
  void flush() const;
  double g(int r, int c) const { return r >= c ? gram_(r, c) : gram_(c, r); }

  GridConfig grid_;
  bool differences_;
  size_t freqs_ = 0;
  int base_ = 0;  // column of the first sin feature
  int dim_ = 0;
  size_t rows_ = 0;
  // Lazily flushed: rows wait in a chunk and enter G by one symmetric rank-k update.
  mutable Eigen::MatrixXd gram_;
  mutable Eigen::MatrixXd chunk_;
  mutable size_t pending_ = 0;
};

}  // namespace fpss::fit
