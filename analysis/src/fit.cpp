#include "fit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "hil/analysis/residuals.hpp"

namespace hil::analysis::detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::size_t kMaxStarts = 12;

}  // namespace

bool solve(std::vector<std::vector<double>> a, std::vector<double> b, std::vector<double>& x) {
  const std::size_t n = b.size();
  for (std::size_t c = 0; c < n; ++c) {
    std::size_t piv = c;
    for (std::size_t r = c + 1; r < n; ++r)
      if (std::abs(a[r][c]) > std::abs(a[piv][c])) piv = r;
    if (!(std::abs(a[piv][c]) > 1e-300)) return false;
    std::swap(a[c], a[piv]);
    std::swap(b[c], b[piv]);
    for (std::size_t r = c + 1; r < n; ++r) {
      const double f = a[r][c] / a[c][c];
      for (std::size_t k = c; k < n; ++k) a[r][k] -= f * a[c][k];
      b[r] -= f * b[c];
    }
  }
  x.assign(n, 0);
  for (std::size_t i = n; i-- > 0;) {
    double s = b[i];
    for (std::size_t k = i + 1; k < n; ++k) s -= a[i][k] * x[k];
    x[i] = s / a[i][i];
  }
  return true;
}

bool invert(const std::vector<std::vector<double>>& a, std::vector<std::vector<double>>& inv) {
  const std::size_t n = a.size();
  inv.assign(n, std::vector<double>(n, 0));
  for (std::size_t c = 0; c < n; ++c) {
    std::vector<double> e(n, 0), x;
    e[c] = 1;
    if (!solve(a, e, x)) return false;
    for (std::size_t r = 0; r < n; ++r) inv[r][c] = x[r];
  }
  return true;
}

Fitter::Fitter(const plant::Plant& model, std::vector<FreeParam> params, const ReplayData& data, unsigned threads)
    : model_(model), params_(std::move(params)), data_(data), threads_(std::max(1u, threads)), yhat_(data.size()) {
  const std::size_t rows = data.segment_end(0) - data.segment_begin(0);
  if (rows >= 2) sample_period_s_ = data.span_s(0) / static_cast<double>(rows - 1);
}

std::vector<double> Fitter::clamp(std::vector<double> x) const {
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = std::clamp(x[i], params_[i].lo, params_[i].hi);
  return x;
}

double Fitter::cost(const std::vector<double>& values, std::vector<double>* residual) {
  return cost_into(values, yhat_, residual);
}

double Fitter::cost_into(const std::vector<double>& values, std::vector<double>& yhat, std::vector<double>* residual) {
  ++evaluations_;
  plant::Plant p = model_;
  try {
    p = with_values(model_, params_, values);
  } catch (const std::invalid_argument&) {
    return kInf;
  }
  if (!replay(p, data_, yhat)) return kInf;
  double rss = 0;
  if (residual) residual->resize(data_.size());
  for (std::size_t k = 0; k < data_.size(); ++k) {
    const double e = data_.y_pa[k] - yhat[k];
    rss += e * e;
    if (residual) (*residual)[k] = e;
  }
  return std::isfinite(rss) ? rss : kInf;
}

std::vector<double> Fitter::best_start(double* rss) {
  // Cartesian product of the starts, capped at kMaxStarts combinations.
  std::vector<std::vector<double>> combos = {{}};
  for (const auto& p : params_) {
    std::vector<std::vector<double>> next;
    for (const auto& c : combos) {
      for (double s : p.starts) {
        auto x = c;
        x.push_back(std::clamp(s, p.lo, p.hi));
        next.push_back(x);
      }
    }
    combos = std::move(next);
  }
  // A lone parameter's starts are all tried (a user effect's log grid, candidates.cpp).
  if (params_.size() > 1 && combos.size() > kMaxStarts) combos.resize(kMaxStarts);
  double best = kInf;
  std::vector<double> best_x = combos.front();
  {
    std::vector<double> costs(combos.size(), kInf);
    run_each(combos.size(), [&](std::vector<double>& yhat, std::size_t i) { costs[i] = cost_into(combos[i], yhat, nullptr); });
    for (std::size_t i = 0; i < combos.size(); ++i)
      if (costs[i] < best) best = costs[i], best_x = combos[i];  // in order: the first of equals, as before
  }
  // A lone parameter on a grid of starts (a user effect's, candidates.cpp) may have a cost with a
  // sharp optimum that LM's finite differences cannot follow (a stick-slip's breakaway 2 % off the
  // truth left 2.2 times the noise): zoom in between the best start's neighbours, three times.
  if (params_.size() == 1 && params_[0].starts.size() > kMaxStarts) {
    std::vector<double> grid = params_[0].starts;
    std::sort(grid.begin(), grid.end());
    const auto at = std::lower_bound(grid.begin(), grid.end(), best_x[0]);
    const std::size_t i = static_cast<std::size_t>(at - grid.begin());
    double lo = grid[i > 0 ? i - 1 : 0], hi = grid[std::min(i + 1, grid.size() - 1)];
    for (int level = 0; level < 3 && hi > lo; ++level) {
      constexpr int kZoom = 16;
      double step = (hi - lo) / kZoom;
      for (int k = 0; k <= kZoom; ++k) {
        const std::vector<double> x = {std::clamp(lo + k * step, params_[0].lo, params_[0].hi)};
        const double c = cost(x);
        if (c < best) best = c, best_x = x;
      }
      lo = best_x[0] - step, hi = best_x[0] + step;
    }
  }
  if (rss) *rss = best;
  return best_x;
}

bool Fitter::jacobian(const std::vector<double>& x, const std::vector<double>& r0, std::vector<std::vector<double>>& cols) {
  cols.assign(x.size(), {});
  std::vector<char> ok(x.size(), 0);
  run_each(x.size(), [&](std::vector<double>& yhat, std::size_t j) {
    // Forward difference of 1 % of the scale (a time: at least one sample period, see
    // FreeParam::sample_step), backwards at the upper bound.
    double h = 0.01 * params_[j].scale;
    if (params_[j].sample_step) h = std::max(h, sample_period_s_);
    auto xp = x;
    xp[j] = x[j] + h;
    if (xp[j] > params_[j].hi) h = -h, xp[j] = x[j] + h;
    std::vector<double>& r = cols[j];
    if (!std::isfinite(cost_into(xp, yhat, &r))) {
      h = -h;
      xp[j] = x[j] + h;
      if (!std::isfinite(cost_into(xp, yhat, &r))) return;
    }
    for (std::size_t k = 0; k < r0.size(); ++k) r[k] = (r[k] - r0[k]) / h;
    ok[j] = 1;
  });
  return std::all_of(ok.begin(), ok.end(), [](char c) { return c != 0; });
}

FitResult Fitter::levenberg_marquardt(std::vector<double> x, int max_iter) {
  FitResult out;
  const std::size_t p = x.size();
  x = clamp(x);
  std::vector<double> r;
  double c = cost(x, &r);
  if (!std::isfinite(c)) {
    out.values = x;
    out.rss = c;
    out.sigma.assign(p, kNaN);
    out.evaluations = evaluations_;
    return out;
  }
  double lambda = 1e-3;
  std::vector<std::vector<double>> cols;
  for (int it = 0; it < max_iter && p > 0; ++it) {
    if (!jacobian(x, r, cols)) break;
    std::vector<std::vector<double>> a(p, std::vector<double>(p, 0));
    std::vector<double> g(p, 0);
    for (std::size_t i = 0; i < p; ++i) {
      for (std::size_t j = i; j < p; ++j) {
        double s = 0;
        for (std::size_t k = 0; k < r.size(); ++k) s += cols[i][k] * cols[j][k];
        a[i][j] = a[j][i] = s;
      }
      double s = 0;
      for (std::size_t k = 0; k < r.size(); ++k) s += cols[i][k] * r[k];
      g[i] = -s;
    }
    bool improved = false;
    std::vector<double> step_taken(p, 0);
    while (lambda < 1e10) {
      auto damped = a;
      for (std::size_t i = 0; i < p; ++i) damped[i][i] += lambda * std::max(a[i][i], 1e-12 * (1 + a[i][i]));
      std::vector<double> dx;
      if (!solve(damped, g, dx)) {
        lambda *= 10;
        continue;
      }
      std::vector<double> xn = x;
      for (std::size_t i = 0; i < p; ++i) xn[i] += dx[i];
      xn = clamp(xn);
      bool moved = false;
      for (std::size_t i = 0; i < p; ++i) moved |= std::abs(xn[i] - x[i]) > 1e-9 * params_[i].scale;
      if (!moved) break;
      std::vector<double> rn;
      const double cn = cost(xn, &rn);
      if (cn < c) {
        for (std::size_t i = 0; i < p; ++i) step_taken[i] = xn[i] - x[i];
        const double rel = (c - cn) / c;
        x = xn, r = std::move(rn), c = cn;
        lambda = std::max(lambda / 5, 1e-9);
        improved = true;
        if (rel < 1e-7) improved = false;  // converged: the cost no longer moves
        break;
      }
      lambda *= 5;
    }
    if (!improved) break;
    bool small = true;
    for (std::size_t i = 0; i < p; ++i) small &= std::abs(step_taken[i]) < 1e-4 * params_[i].scale;
    if (small) break;
  }
  out.values = x;
  out.rss = c;
  out.ok = std::isfinite(c);
  out.evaluations = evaluations_;
  return out;
}

std::vector<double> Fitter::uncertainty(const std::vector<double>& x, std::vector<std::vector<double>>* correlation) {
  if (correlation) correlation->clear();
  const std::size_t p = x.size();
  std::vector<double> sigma(p, kNaN);
  std::vector<double> r;
  const double c = cost(x, &r);
  std::vector<std::vector<double>> cols;
  const std::size_t n = data_.scored_rows();  // a run's left-out rows carry no residual
  if (!std::isfinite(c) || p == 0 || n <= p || !jacobian(x, r, cols)) return sigma;
  std::vector<std::vector<double>> a(p, std::vector<double>(p, 0)), inv;
  for (std::size_t i = 0; i < p; ++i)
    for (std::size_t j = i; j < p; ++j) {
      double s = 0;
      for (std::size_t k = 0; k < r.size(); ++k) s += cols[i][k] * cols[j][k];
      a[i][j] = a[j][i] = s;
    }
  if (!invert(a, inv)) return sigma;
  const double s2 = c / static_cast<double>(n - p);
  const double tau = integrated_autocorrelation_time(r);
  for (std::size_t i = 0; i < p; ++i) {
    if (inv[i][i] > 0) sigma[i] = std::sqrt(s2 * tau * inv[i][i]);
  }
  if (correlation) {
    correlation->assign(p, std::vector<double>(p, kNaN));
    for (std::size_t i = 0; i < p; ++i)
      for (std::size_t j = 0; j < p; ++j)
        if (inv[i][i] > 0 && inv[j][j] > 0) (*correlation)[i][j] = inv[i][j] / std::sqrt(inv[i][i] * inv[j][j]);
  }
  return sigma;
}

}  // namespace hil::analysis::detail
