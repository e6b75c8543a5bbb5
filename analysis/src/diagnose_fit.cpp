// diagnose's fitting of one candidate (diagnose_search.hpp): a variant by LM and grid search, joint
// refits of the added effects, a step time's profile.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "diagnose_search.hpp"
#include "fit.hpp"
#include "hil/analysis/compare.hpp"
#include "hil/units.hpp"
#include "text.hpp"

namespace hil::analysis::detail {

double rss_of(const plant::Plant& model, const ReplayData& data, std::vector<double>* residual) {
  std::vector<double> yhat(data.size());
  if (!replay(model, data, yhat)) return kInf;
  double rss = 0;
  if (residual) residual->resize(data.size());
  for (std::size_t k = 0; k < data.size(); ++k) {
    const double e = data.y_pa[k] - yhat[k];
    rss += e * e;
    if (residual) (*residual)[k] = e;
  }
  return rss;
}

Score score_of(const Context& ctx, const plant::Plant& model) {
  std::vector<double> res;
  Score sc;
  sc.rss = rss_of(model, ctx.full, &res);
  if (std::isfinite(sc.rss)) sc.wrss = ctx.criterion.whitened_rss(res);
  return sc;
}

plant::Plant model_for(const plant::Plant& attached, const VariantFit& v, double grid_value) {
  if (v.grid == nullptr) return attached;
  return with_values(attached, {*v.grid}, {grid_value});
}

// vf's variant's parameters: the grid one (at most one) and the continuous ones.
void split_params(const Candidate& cand, VariantFit& vf) {
  for (const auto& p : cand.variants[vf.variant].params) {
    if (p.grid)
      vf.grid = &p;
    else
      vf.continuous.push_back(p);
  }
}

void fit_variant(const Context& ctx, const plant::Plant& base, const Candidate& cand, VariantFit& vf) {
  throw_if_cancelled(ctx.cancel);
  const plant::Plant attached = cand.attach(base);
  split_params(cand, vf);
  const bool same = &ctx.coarse == &ctx.full || ctx.coarse.size() == ctx.full.size();
  if (vf.grid) {
    const auto values = vf.grid->grid_values ? vf.grid->grid_values(ctx.coarse) : std::vector<double>{};
    if (values.empty()) {
      vf.note = "no place for it in the data (e.g. fewer than two motion reversals)";
      return;
    }
    // Zoom search: kGridCoarse evenly spread values, then kGridZoom values around the best one
    // at a quarter of the spacing, and so on down to neighbouring values. Each value is a short
    // LM on the continuous parameters, warm-started from the best fit so far; the values of one
    // level run on all threads (this is the longest job of a round).
    const std::size_t n = values.size();
    std::vector<double> warm;
    {
      const plant::Plant m = with_values(attached, {*vf.grid}, {values[n / 2]});
      detail::Fitter f(m, vf.continuous, ctx.coarse);
      warm = f.best_start(nullptr);
      vf.evaluations += f.evaluations();
    }
    double best = kInf;
    std::size_t best_i = n / 2;
    std::vector<bool> tried(n, false);
    std::size_t lo = 0, hi = n - 1, stride = std::max<std::size_t>(1, (n + kGridCoarse - 1) / kGridCoarse);
    for (;;) {
      throw_if_cancelled(ctx.cancel);  // a level is the longest unit of a round
      std::vector<std::size_t> level;
      for (std::size_t i = lo + stride / 2; i <= hi; i += stride)
        if (!tried[i]) level.push_back(i), tried[i] = true;
      std::vector<detail::FitResult> results(level.size());
      std::vector<int> evals(level.size(), 0);
      parallel_for(level.size(), ctx.threads, [&](std::size_t j) {
        const plant::Plant m = with_values(attached, {*vf.grid}, {values[level[j]]});
        detail::Fitter f(m, vf.continuous, ctx.coarse);
        results[j] = f.levenberg_marquardt(warm, kGridIter);
        evals[j] = f.evaluations();
      });
      for (std::size_t j = 0; j < level.size(); ++j) {
        vf.evaluations += evals[j];
        if (results[j].rss < best)
          best = results[j].rss, best_i = level[j], vf.grid_value = values[level[j]], vf.values = results[j].values;
      }
      if (std::isfinite(best)) warm = vf.values;
      if (stride == 1 || !std::isfinite(best)) break;
      lo = best_i >= stride ? best_i - stride : 0;
      hi = std::min(n - 1, best_i + stride);
      stride = std::max<std::size_t>(1, (hi - lo + kGridZoom - 1) / kGridZoom);
    }
    if (!std::isfinite(best)) {
      vf.note = "the model cannot be replayed with this effect";
      return;
    }
  }
  const plant::Plant m = model_for(attached, vf, vf.grid_value);
  detail::Fitter f(m, vf.continuous, ctx.coarse);
  std::vector<double> x0 = vf.values;
  if (x0.empty()) x0 = f.best_start(nullptr);
  const auto r = f.levenberg_marquardt(x0, kCoarseIter);
  vf.values = r.values;
  vf.sigma = f.uncertainty(vf.values);
  vf.evaluations += f.evaluations();
  if (!r.ok) {
    vf.note = "the model cannot be replayed with this effect";
    return;
  }
  vf.rss_coarse = r.rss;
  if (same) {
    const Score sc = score_of(ctx, with_values(m, vf.continuous, vf.values));
    vf.rss_full = sc.rss, vf.wrss_full = sc.wrss;
    ++vf.evaluations;
    vf.refined = true;
  }
}

// RSS on every row at the coarse fit's values.
void evaluate_full(const Context& ctx, const plant::Plant& base, const Candidate& cand, VariantFit& vf) {
  throw_if_cancelled(ctx.cancel);
  const plant::Plant m = model_for(cand.attach(base), vf, vf.grid_value);
  const Score sc = score_of(ctx, with_values(m, vf.continuous, vf.values));
  vf.rss_full = sc.rss, vf.wrss_full = sc.wrss;
  ++vf.evaluations;
}

void refine_variant(const Context& ctx, const plant::Plant& base, const Candidate& cand, VariantFit& vf) {
  throw_if_cancelled(ctx.cancel);
  if (vf.refined || !std::isfinite(vf.rss_full)) return;
  const plant::Plant m = model_for(cand.attach(base), vf, vf.grid_value);
  detail::Fitter f(m, vf.continuous, ctx.full);
  const auto r = f.levenberg_marquardt(vf.values, kRefineIter);
  if (r.ok && r.rss < vf.rss_full) {
    vf.values = r.values;
    const Score sc = score_of(ctx, with_values(m, vf.continuous, vf.values));
    vf.rss_full = sc.rss, vf.wrss_full = sc.wrss;
    ++vf.evaluations;
  }
  vf.sigma = f.uncertainty(vf.values);
  vf.evaluations += f.evaluations();
  vf.refined = true;
}

CandidateResult describe(const Candidate& cand, const VariantFit& vf, const plant::Plant& base) {
  CandidateResult c;
  c.effect = cand.name;
  c.variant = cand.variants[vf.variant].name;
  c.description = cand.description;
  c.rss_pa2 = vf.rss_full;
  c.k = vf.k();
  c.refined = vf.refined;
  c.evaluations = vf.evaluations;
  for (std::size_t i = 0; i < vf.continuous.size(); ++i) {
    const auto& p = vf.continuous[i];
    c.parameters.push_back({p.effect, p.key, vf.values.empty() ? kNaN : vf.values[i], i < vf.sigma.size() ? vf.sigma[i] : kNaN,
                            value_of(base, p.effect, p.key), false});
    c.parameters.back().search_lo = p.lo;
    c.parameters.back().search_hi = p.hi;
    c.parameters.back().credible_lo = p.credible_lo;
    c.parameters.back().credible_hi = p.credible_hi;
    c.parameters.back().credible_why = p.credible_why;
  }
  if (vf.grid) {
    c.parameters.push_back(
        {vf.grid->effect, vf.grid->key, vf.grid_value, kNaN, value_of(base, vf.grid->effect, vf.grid->key), true});
  }
  c.why_not = vf.note;
  return c;
}

plant::Plant apply_added(const plant::Plant& model, const std::vector<Added>& added) {
  plant::Plant p = model;
  for (const auto& a : added) {
    p = a.cand->attach(p);
    if (a.fit.grid) p = with_values(p, {*a.fit.grid}, {a.fit.grid_value});
    p = with_values(p, a.fit.continuous, a.fit.values);
  }
  return p;
}

// Jointly refits every added effect's continuous parameters (the first fit of an effect absorbed
// part of the ones found after it).
void joint_refit(const Context& ctx, const plant::Plant& base0, std::vector<Added>& added, int& evaluations) {
  throw_if_cancelled(ctx.cancel);
  std::vector<FreeParam> params;
  std::vector<double> x;
  for (const auto& a : added) {
    params.insert(params.end(), a.fit.continuous.begin(), a.fit.continuous.end());
    x.insert(x.end(), a.fit.values.begin(), a.fit.values.end());
  }
  if (params.empty()) return;
  const plant::Plant m = apply_added(base0, added);  // values are overwritten by the fitter
  const bool decimated = ctx.coarse.size() != ctx.full.size();
  // Two starts: the values as they are, and the best of the parameters' own starting points: an
  // effect found first may have absorbed one found later (a sensor lag standing in for a transport
  // delay takes twice its time constant), and LM from there stays in that valley.
  std::vector<std::vector<double>> starts = {x};
  {
    detail::Fitter f0(m, params, ctx.coarse, ctx.threads);
    std::vector<double> fresh = f0.best_start(nullptr);
    evaluations += f0.evaluations();
    if (fresh != x) starts.push_back(std::move(fresh));
  }
  // LM from the starts `which` on `data`: side by side, one thread each (a lone start: its
  // Jacobian's columns on all threads). A start moves to where its LM ended when it could be replayed.
  std::vector<double> rss(starts.size(), kInf);
  std::atomic<int> evals{0};
  auto fit_from = [&](const ReplayData& data, int iter, const std::vector<std::size_t>& which) {
    const unsigned inner = which.size() > 1 ? 1 : ctx.threads;
    parallel_for(which.size(), ctx.threads, [&](std::size_t j) {
      const std::size_t i = which[j];
      detail::Fitter f(m, params, data, inner);
      const auto r = f.levenberg_marquardt(starts[i], iter);
      evals += f.evaluations();
      if (r.ok) starts[i] = r.values;
      rss[i] = r.ok ? r.rss : kInf;
    });
  };
  std::vector<std::size_t> which(starts.size());
  for (std::size_t i = 0; i < which.size(); ++i) which[i] = i;
  if (decimated) {
    // On the coarse copy first; then every row only for the ends within kJointTie of the best
    // coarse end: a few LM iterations on every row polish an end, they do not turn a valley that
    // fits the coarse copy clearly worse into the better one, and on a long file each is most of
    // the refit's cost.
    fit_from(ctx.coarse, kJointIter, which);
    const double best_coarse = *std::min_element(rss.begin(), rss.end());
    if (std::isfinite(best_coarse)) {
      std::vector<std::size_t> close;
      for (std::size_t i : which)
        if (rss[i] <= (1 + kJointTie) * best_coarse) close.push_back(i);
      which = std::move(close);
    }
    for (double& r : rss) r = kInf;
    fit_from(ctx.full, kRefineIter, which);
  } else {
    fit_from(ctx.full, kJointIter, which);
  }
  evaluations += evals.load();
  std::size_t best = 0;  // the first start wins a tie
  for (std::size_t i = 1; i < starts.size(); ++i)
    if (rss[i] < rss[best]) best = i;
  x = std::move(starts[best]);
  detail::Fitter f(m, params, ctx.full, ctx.threads);
  const auto sigma = f.uncertainty(x);
  evaluations += f.evaluations();
  std::size_t i = 0;
  for (auto& a : added) {
    for (std::size_t j = 0; j < a.fit.values.size(); ++j, ++i) {
      a.fit.values[j] = x[i];
      if (i < sigma.size()) a.fit.sigma[j] = sigma[i];
    }
  }
}

// Refits a candidate on every row together with the accepted effects (none held fixed): an
// effect accepted earlier may have absorbed part of this one, and a fit of the newcomer against
// it frozen would understate what the two explain together (valve offset against an erosion that
// took part of it). The candidate's RSS for the criterion is the joint one.
void refine_jointly(const Context& ctx, const plant::Plant& base0, const std::vector<Added>& added, const Candidate& cand,
                    VariantFit& vf) {
  throw_if_cancelled(ctx.cancel);
  if (!std::isfinite(vf.rss_full)) return;
  std::vector<FreeParam> params;
  std::vector<double> x;
  for (const auto& a : added) {
    params.insert(params.end(), a.fit.continuous.begin(), a.fit.continuous.end());
    x.insert(x.end(), a.fit.values.begin(), a.fit.values.end());
  }
  const std::size_t n_added = x.size();
  if (n_added == 0) return;
  params.insert(params.end(), vf.continuous.begin(), vf.continuous.end());
  x.insert(x.end(), vf.values.begin(), vf.values.end());
  const plant::Plant m = model_for(cand.attach(apply_added(base0, added)), vf, vf.grid_value);
  detail::Fitter f(m, params, ctx.full);
  const auto r = f.levenberg_marquardt(x, kRefineIter);
  vf.evaluations += f.evaluations();
  if (!r.ok || !(r.rss < vf.rss_full)) return;
  const Score sc = score_of(ctx, with_values(m, params, r.values));
  vf.evaluations += 1;
  vf.rss_full = sc.rss, vf.wrss_full = sc.wrss;
  vf.added_values.assign(r.values.begin(), r.values.begin() + static_cast<std::ptrdiff_t>(n_added));
  vf.values.assign(r.values.begin() + static_cast<std::ptrdiff_t>(n_added), r.values.end());
  const auto sigma = f.uncertainty(r.values);
  vf.evaluations += f.evaluations();
  if (sigma.size() == r.values.size()) vf.sigma.assign(sigma.begin() + static_cast<std::ptrdiff_t>(n_added), sigma.end());
}

// Takes over the accepted effects' values that the chosen candidate's joint refine found.
void adopt_joint_values(std::vector<Added>& added, const VariantFit& chosen) {
  if (chosen.added_values.empty()) return;
  std::size_t i = 0;
  for (auto& a : added)
    for (double& v : a.fit.values)
      if (i < chosen.added_values.size()) v = chosen.added_values[i++];
}

// How far an added effect's grid parameter (a step time) can move and still fit: its profile.
// A step is located only by the motions around it; between two motions every time fits as well,
// and the best grid value alone would claim more than the data say. From the chosen value the
// walk steps outwards, doubling its stride while the cost stays within one standard error of the
// best (the RSS of the coarse copy may rise by s^2 tau: the residual's variance times its
// correlation time, a one-parameter chi-square of 1 for correlated noise), then bisects to the
// last grid value inside. At each value the effect's continuous parameters are refitted (a short
// LM from their values), the other effects held. Both directions run at once. NaN when the
// effect has no grid parameter.
std::pair<double, double> grid_span(const Context& ctx, const plant::Plant& base0, const std::vector<Added>& added,
                                    std::size_t which, int& evaluations) {
  const VariantFit& fit = added[which].fit;
  if (fit.grid == nullptr || !fit.grid->grid_values) return {kNaN, kNaN};
  const std::vector<double> values = fit.grid->grid_values(ctx.coarse);
  if (values.size() < 2) return {kNaN, kNaN};
  std::atomic<int> evals{0};
  auto cost = [&](double g) {
    throw_if_cancelled(ctx.cancel);
    std::vector<Added> trial = added;
    trial[which].fit.grid_value = g;
    const plant::Plant m = apply_added(base0, trial);
    if (fit.continuous.empty()) {
      ++evals;
      return rss_of(m, ctx.coarse, nullptr);
    }
    detail::Fitter f(m, fit.continuous, ctx.coarse);
    const auto r = f.levenberg_marquardt(fit.values, kGridIter);
    evals += f.evaluations();
    return r.ok ? r.rss : kInf;
  };
  std::vector<double> residual;
  const double rss_now = rss_of(apply_added(base0, added), ctx.coarse, &residual);
  std::size_t k = 0;
  for (const auto& a : added) k += a.fit.k();
  if (!std::isfinite(rss_now) || residual.size() <= k + 1) return {kNaN, kNaN};
  const double s2 = rss_now / static_cast<double>(residual.size() - k);
  const double within = std::min(rss_now, cost(fit.grid_value)) + s2 * integrated_autocorrelation_time(residual);
  std::size_t best = 0;
  for (std::size_t i = 1; i < values.size(); ++i)
    if (std::abs(values[i] - fit.grid_value) < std::abs(values[best] - fit.grid_value)) best = i;
  double ends[2] = {values[best], values[best]};
  parallel_for(2, ctx.threads, [&](std::size_t side) {
    const long dir = side == 0 ? -1 : 1, last = side == 0 ? 0 : static_cast<long>(values.size()) - 1;
    long in = static_cast<long>(best), stride = 1;
    for (;;) {
      const long j = dir < 0 ? std::max(last, in - stride) : std::min(last, in + stride);
      if (j == in) break;  // the span reaches the data's end
      if (cost(values[static_cast<std::size_t>(j)]) <= within) {
        in = j, stride *= 2;
        continue;
      }
      for (long out = j; std::abs(out - in) > 1;) {  // the last value inside lies between
        const long mid = (in + out) / 2;
        (cost(values[static_cast<std::size_t>(mid)]) <= within ? in : out) = mid;
      }
      break;
    }
    ends[side] = values[static_cast<std::size_t>(in)];
  });
  evaluations += evals.load();
  return {ends[0], ends[1]};
}

}  // namespace hil::analysis::detail
