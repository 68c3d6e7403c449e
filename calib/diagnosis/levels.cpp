// Each recording's own level in a joint diagnosis of recordings that do not share a clock: a
// candidate with a constant per axis for every such recording after the first, fitted with it.
#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include "calib/diagnosis/internal.h"

namespace fpss::diag {
namespace {

using Rows = std::vector<uint32_t>;
using Ranges = std::vector<std::pair<size_t, size_t>>;

// A candidate (or none) with a level per axis on each range of rows. The levels are shared by
// every candidate alike (the baseline `none` has them too), so they do not count in its
// parameters. A linear candidate is solved with its levels in one least-squares problem; a
// nonlinear one alternates its fit with the levels' (backfitting, a few passes).
class Levelled : public Candidate {
 public:
  Levelled(std::unique_ptr<Candidate> inner, Ranges parts)
      : inner_(std::move(inner)), parts_(std::move(parts)), level_(parts_.size(), {0.0, 0.0}) {}
  Levelled(const Levelled& o)
      : inner_(o.inner_ ? o.inner_->clone() : nullptr), parts_(o.parts_), level_(o.level_) {}

  std::string name() const override { return inner_ ? inner_->name() : "none"; }
  int parameters() const override { return inner_ ? inner_->parameters() : 0; }
  std::unique_ptr<Candidate> clone() const override { return std::make_unique<Levelled>(*this); }

  void fit(const Recording& r, const Contribution& target, const Rows& rows) override {
    std::fill(level_.begin(), level_.end(), std::array<double, 2>{0.0, 0.0});
    Contribution own;  // the inner candidate's contribution (zero for none)
    own.resize(r.n);
    if (!inner_) return set_levels(target, own, rows);
    Contribution shifted = target;
    for (int pass = 0; pass < 3; ++pass) {
      for (size_t k = 0; k < parts_.size(); ++k) {
        for (int a = 0; a < 2; ++a) {
          if (shifted.v[a].empty()) continue;
          for (size_t i = parts_[k].first; i < parts_[k].second; ++i) shifted.v[a][i] = target.at(a, i) - level_[k][a];
        }
      }
      inner_->fit(r, shifted, rows);
      inner_->contribute(r, own);
      set_levels(target, own, rows);
    }
    if (inner_->columns() > 0) solve_linear(r, target, rows);
  }

  void contribute(const Recording& r, Contribution& out) const override {
    if (inner_) {
      inner_->contribute(r, out);
    } else {
      out.resize(r.n);
    }
    for (size_t k = 0; k < parts_.size(); ++k) {
      for (int a = 0; a < 2; ++a) {
        if (out.v[a].empty()) out.v[a].assign(r.n, 0.0f);
        for (size_t i = parts_[k].first; i < parts_[k].second; ++i) out.v[a][i] += static_cast<float>(level_[k][a]);
      }
    }
  }

  nlohmann::ordered_json params() const override { return inner_ ? inner_->params() : nlohmann::ordered_json::object(); }
  void set(const EffectParams& p) override {
    if (inner_) inner_->set(p);
    std::fill(level_.begin(), level_.end(), std::array<double, 2>{0.0, 0.0});
  }
  nlohmann::ordered_json notes() const override {
    nlohmann::ordered_json n = inner_ ? inner_->notes() : nlohmann::ordered_json::object();
    nlohmann::ordered_json levels = nlohmann::ordered_json::array();
    for (const auto& l : level_) levels.push_back({l[0], l[1]});
    n["recording_levels_arcsec"] = levels;  // pitch, yaw of each recording after the first on its own clock
    return n;
  }

  int columns() const override {
    const int m = inner_ ? inner_->columns() : 0;
    return m > 0 ? m + 2 * static_cast<int>(parts_.size()) : 0;
  }
  void column_values(const Recording& r, size_t i, int a, double* v) const override {
    const int m = inner_->columns();
    inner_->column_values(r, i, a, v);
    for (size_t k = 0; k < parts_.size(); ++k) {
      const bool in = i >= parts_[k].first && i < parts_[k].second;
      v[m + 2 * k] = in && a == 0 ? 1.0 : 0.0;
      v[m + 2 * k + 1] = in && a == 1 ? 1.0 : 0.0;
    }
  }
  double column_offset(const Recording& r, size_t i, int a) const override { return inner_->column_offset(r, i, a); }
  void set_linear(const std::vector<double>& w) override {
    const size_t m = static_cast<size_t>(inner_->columns());
    inner_->set_linear(std::vector<double>(w.begin(), w.begin() + static_cast<std::ptrdiff_t>(m)));
    for (size_t k = 0; k < parts_.size(); ++k) level_[k] = {w[m + 2 * k], w[m + 2 * k + 1]};
  }
  void hold(const std::string& key, double value) override { if (inner_) inner_->hold(key, value); }
  void restart() override { if (inner_) inner_->restart(); }
  std::string degenerate() const override { return inner_ ? inner_->degenerate() : std::string(); }

 private:
  // Each level: the mean over its rows among `rows` (ascending, as the split makes them) of what the
  // inner candidate leaves.
  void set_levels(const Contribution& target, const Contribution& own, const Rows& rows) {
    for (size_t k = 0; k < parts_.size(); ++k) {
      const auto lo = std::lower_bound(rows.begin(), rows.end(), static_cast<uint32_t>(parts_[k].first));
      const auto hi = std::lower_bound(rows.begin(), rows.end(), static_cast<uint32_t>(parts_[k].second));
      for (int a = 0; a < 2; ++a) {
        double s = 0;
        for (auto it = lo; it != hi; ++it) s += target.at(a, *it) - own.at(a, *it);
        level_[k][a] = hi > lo ? s / static_cast<double>(hi - lo) : 0.0;
      }
    }
  }

  // The inner candidate's columns and the levels in one least-squares solve on `rows`.
  void solve_linear(const Recording& r, const Contribution& target, const Rows& rows) {
    const int m = columns();
    const Eigen::VectorXd w = solve_columns(rows, m, [&](uint32_t i, int a, double* v) {
      column_values(r, i, a, v);
      return target.at(a, i) - column_offset(r, i, a);
    });
    set_linear(std::vector<double>(w.data(), w.data() + m));
  }

  std::unique_ptr<Candidate> inner_;
  Ranges parts_;
  std::vector<std::array<double, 2>> level_;
};

}  // namespace

std::vector<std::pair<size_t, size_t>> levelled_parts(const Recording& r) {
  Ranges out;
  size_t from = 0;
  for (size_t k = 0; k < r.parts.size(); ++k) {
    if (k > 0 && r.parts[k].clock == JointClock::own) out.emplace_back(from, from + r.parts[k].rows);
    from += r.parts[k].rows;
  }
  return out;
}

std::unique_ptr<Candidate> make_candidate(const std::string& name, const Recording& r) {
  auto c = name == "none" ? nullptr : make_candidate(name);
  Ranges parts = levelled_parts(r);
  if (parts.empty() || (!c && name != "none")) return c;
  return std::make_unique<Levelled>(std::move(c), std::move(parts));
}

}  // namespace fpss::diag
