// sirad: the paper's cost and error model (see model/model.h).
#include "model/model.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "util/error.h"

namespace sirad::model {

namespace {

constexpr double kNone = -std::numeric_limits<double>::infinity();

// ln(e^x + e^y) without overflow; -inf is zero.
double log_add(double x, double y) {
  if (x == kNone) return y;
  if (y == kNone) return x;
  double hi = std::max(x, y), lo = std::min(x, y);
  return hi + std::log1p(std::exp(lo - hi));
}

// Bounces whose weight a^(2(k-1)) is above 1e-40: beyond them a path's share of the error and
// of E is nothing next to the first bounce's (s(1) = N P), and s(k) needs only s(1..k), so
// keeping the first ones is exact for them.
uint64_t bounces_that_matter(double a, uint64_t iterations) {
  if (a <= 0.0) return std::min<uint64_t>(iterations, 1);
  double k = 1.0 + 40.0 * std::log(10.0) / (-2.0 * std::log(a));
  return std::min<uint64_t>(iterations, static_cast<uint64_t>(std::ceil(k)));
}

}  // namespace

double combined_factor(uint32_t processors, double fraction) {
  return 1.0 + (static_cast<double>(processors) - 1.0) * fraction;
}

namespace {

// ln of the closed form for K phases (K real for the search over I).
double log_closed(double phases, double period, uint32_t processors, double fraction, double a) {
  const double p = static_cast<double>(processors), a2 = a * a;
  if (phases <= 0.0) return kNone;
  // A = P ((a^2 + 1)^I - 1) / a^2  (-> P I at a = 0)
  double log_a_term = a2 > 0.0 ? std::log(p) + std::log(std::expm1(period * std::log1p(a2))) - std::log(a2)
                               : std::log(p * period);
  // B = (a^2 + 1)^(I-1) (c a^2 + 1), c = combined_factor; (B^K - 1) / (B - 1)  (-> K at B = 1)
  double log_b = (period - 1.0) * std::log1p(a2) + std::log1p(combined_factor(processors, fraction) * a2);
  double log_sum;
  if (log_b <= 0.0) {
    log_sum = std::log(phases);
  } else {
    double kb = phases * log_b;
    log_sum = kb + std::log(-std::expm1(-kb)) - std::log(std::expm1(log_b));
  }
  return log_a_term + log_sum;
}

double phases_in(double time, double period, const Setup& setup, const Costs& costs) {
  return time / (costs.t_iteration * period + costs.t_exchange * setup.processors * setup.fraction);
}

// The longest period with at least one whole phase in `time` (K(I) >= 1; the closed form
// assumes every phase runs its I steps), within max_period; at least 1.
uint64_t longest_period(double time, const Setup& setup, const Costs& costs, uint64_t max_period) {
  double i = (time - costs.t_exchange * setup.processors * setup.fraction) / costs.t_iteration;
  uint64_t whole = i >= 1.0 ? static_cast<uint64_t>(std::floor(i * (1 + 1e-12))) : 1;
  return std::clamp<uint64_t>(whole, 1, std::max<uint64_t>(max_period, 1));
}

}  // namespace

void check(const Setup& s) {
  if (s.processors < 1 || s.processors > 1000000) fail("model: processors P = {} outside [1, 1e6]", s.processors);
  if (!(s.fraction > 0.0 && s.fraction <= 1.0)) fail("model: fraction S = {} outside (0, 1]", s.fraction);
}

void check(const Costs& c) {
  if (!(c.t_iteration > 0.0) || !std::isfinite(c.t_iteration)) fail("model: iteration time T_i = {} is not positive", c.t_iteration);
  if (!(c.t_exchange >= 0.0) || !std::isfinite(c.t_exchange)) fail("model: exchange time T_e = {} is negative", c.t_exchange);
}

void check(const Scene& s) {
  if (!(s.contraction >= 0.0 && s.contraction < 1.0)) fail("model: contraction a = {} outside [0, 1)", s.contraction);
  if (!(s.sigma_ratio > 0.0) || !std::isfinite(s.sigma_ratio)) fail("model: sigma_1 / C = {} is not positive", s.sigma_ratio);
}

double total_time(uint64_t iterations, const Setup& setup, const Costs& costs) {
  check(setup);
  check(costs);
  double n = static_cast<double>(iterations);
  double exchanges = setup.exchange_every == 0 ? 0.0 : n / static_cast<double>(setup.exchange_every);
  return n * costs.t_iteration + exchanges * setup.processors * setup.fraction * costs.t_exchange;
}

uint64_t iterations_in(double time, const Setup& setup, const Costs& costs) {
  check(setup);
  check(costs);
  if (!(time >= 0.0) || !std::isfinite(time)) fail("model: time T = {} is not a finite, non-negative number", time);
  if (setup.exchange_every == 0) return static_cast<uint64_t>(std::floor(time / costs.t_iteration * (1 + 1e-12)));
  double i = static_cast<double>(setup.exchange_every);
  double n = time * i / (costs.t_iteration * i + costs.t_exchange * setup.processors * setup.fraction);
  return static_cast<uint64_t>(std::floor(n * (1 + 1e-12)));  // 60 s / 4.5 s... exact quotients stay whole
}

std::vector<double> log_sample_numbers(uint64_t iterations, const Setup& setup, uint64_t max_bounces) {
  check(setup);
  const uint64_t kmax = max_bounces == 0 ? iterations : std::min(iterations, max_bounces);
  std::vector<double> ls(kmax, kNone);
  const double log_p = std::log(static_cast<double>(setup.processors));
  const double log_ps = std::log(combined_factor(setup.processors, setup.fraction));
  for (uint64_t n = 0; n < iterations; ++n) {
    const bool combined = setup.exchange_every > 0 && n % setup.exchange_every == 0;
    const double log_c = combined ? log_ps : 0.0;
    // s(k+1) += c s(k), from the longest down so every s(k) used is the step's old one.
    for (uint64_t k = std::min<uint64_t>(n, kmax - 1); k >= 1; --k) ls[k] = log_add(ls[k], log_c + ls[k - 1]);
    if (kmax > 0) ls[0] = log_add(ls[0], log_p);
  }
  return ls;
}

double relative_error(const std::vector<double>& log_samples, const Scene& scene, uint64_t longest) {
  check(scene);
  const double a = scene.contraction;
  const uint64_t n = longest == 0 ? log_samples.size() : longest;
  double sum = 0.0;
  for (std::size_t k = 0; k < log_samples.size(); ++k) {
    if (log_samples[k] == kNone) continue;
    double weight = k == 0 ? 1.0 : std::pow(a, 2.0 * static_cast<double>(k));
    sum += weight * std::exp(-log_samples[k]);
  }
  double bias = std::pow(a, static_cast<double>(n) + 1.0);
  return bias + 3.0 * (1.0 - a) * scene.sigma_ratio * std::sqrt(sum);
}

double log_effective_samples(const std::vector<double>& log_samples, double contraction) {
  if (!(contraction >= 0.0 && contraction < 1.0)) fail("model: contraction a = {} outside [0, 1)", contraction);
  double out = kNone;
  const double log_a2 = contraction > 0.0 ? 2.0 * std::log(contraction) : kNone;
  for (std::size_t k = 0; k < log_samples.size(); ++k) {
    if (log_samples[k] == kNone) continue;
    if (k > 0 && contraction == 0.0) break;
    out = log_add(out, log_samples[k] + (k == 0 ? 0.0 : static_cast<double>(k) * log_a2));
  }
  return out;
}

double log_effective_samples_closed(uint64_t phases, const Setup& setup, double contraction) {
  check(setup);
  if (!(contraction >= 0.0 && contraction < 1.0)) fail("model: contraction a = {} outside [0, 1)", contraction);
  if (setup.exchange_every == 0) fail("model: the closed form needs an exchange period I >= 1");
  return log_closed(static_cast<double>(phases), static_cast<double>(setup.exchange_every), setup.processors,
                    setup.fraction, contraction);
}

Prediction predict(double time, const Setup& setup, const Costs& costs, const Scene& scene) {
  check(scene);
  Prediction p;
  p.iterations = iterations_in(time, setup, costs);
  p.phases = setup.exchange_every == 0 ? 0 : p.iterations / setup.exchange_every;
  auto ls = log_sample_numbers(p.iterations, setup, bounces_that_matter(scene.contraction, p.iterations));
  // No iteration fits in the time: nothing is estimated.
  p.relative_error = ls.empty() ? std::numeric_limits<double>::infinity() : relative_error(ls, scene, p.iterations);
  p.log_effective = log_effective_samples(ls, scene.contraction);
  p.bias = std::pow(scene.contraction, static_cast<double>(p.iterations) + 1);
  p.sd = std::isfinite(p.relative_error) ? (p.relative_error - p.bias) / 3 : std::numeric_limits<double>::infinity();
  return p;
}

double time_to_error(double target, const Setup& setup, const Costs& costs, const Scene& scene, uint64_t max_iterations) {
  check(setup);
  check(costs);
  check(scene);
  auto error = [&](uint64_t n) {
    auto ls = log_sample_numbers(n, setup, bounces_that_matter(scene.contraction, n));
    return relative_error(ls, scene, n);
  };
  // Doubling until the target is met (it is met early for any practical target), then bisection.
  uint64_t lo = 0, hi = 1;  // error(lo) > target (N = 0: unbounded), error(hi) <= target
  while (!(error(hi) <= target)) {
    if (hi >= max_iterations) return std::numeric_limits<double>::infinity();
    lo = hi;
    hi = std::min(2 * hi, max_iterations);
  }
  while (hi - lo > 1) {
    uint64_t mid = lo + (hi - lo) / 2;
    (error(mid) <= target ? hi : lo) = mid;
  }
  return total_time(hi, setup, costs);
}

uint64_t brute_force_period(double time, Setup setup, const Costs& costs, double contraction, uint64_t max_period) {
  check(setup);
  check(costs);
  uint64_t best = 1;
  double best_e = kNone;
  const uint64_t last = longest_period(time, setup, costs, max_period);
  for (uint64_t i = 1; i <= last; ++i) {
    double e = log_closed(phases_in(time, static_cast<double>(i), setup, costs), static_cast<double>(i), setup.processors,
                          setup.fraction, contraction);
    if (e > best_e) {
      best_e = e;
      best = i;
    }
  }
  return best;
}

uint64_t best_period(double time, Setup setup, const Costs& costs, double contraction, uint64_t max_period) {
  check(setup);
  check(costs);
  auto f = [&](double i) {
    return log_closed(phases_in(time, i, setup, costs), i, setup.processors, setup.fraction, contraction);
  };
  const uint64_t last = longest_period(time, setup, costs, max_period);
  double lo = 1.0, hi = static_cast<double>(last);
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1 = f(x1), f2 = f(x2);
  while (hi - lo > 0.5) {
    if (f1 < f2) {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + g * (hi - lo);
      f2 = f(x2);
    } else {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - g * (hi - lo);
      f1 = f(x1);
    }
  }
  // The whole periods around the continuous optimum (and the ends, where it may sit).
  uint64_t best = 1;
  double best_e = kNone;
  const uint64_t centre = static_cast<uint64_t>(std::llround(0.5 * (lo + hi)));
  for (uint64_t i : {centre > 1 ? centre - 1 : 1, centre, centre + 1, uint64_t{1}, last}) {
    if (i < 1 || i > last) continue;
    double e = f(static_cast<double>(i));
    if (e > best_e || (e == best_e && i < best)) {
      best_e = e;
      best = i;
    }
  }
  return best;
}

ExchangeChoice choose_exchange(double time, uint32_t processors, const Costs& costs, const Scene& scene,
                               uint64_t max_period, double min_fraction) {
  check(costs);
  check(scene);
  if (processors == 0) fail("model: processors must be at least 1");
  ExchangeChoice best;
  best.prediction.relative_error = std::numeric_limits<double>::infinity();
  const uint64_t fit = std::max<uint64_t>(1, iterations_in(time, {processors, 0, 1.0}, costs));
  const uint64_t last = std::max<uint64_t>(1, std::min(max_period, fit));
  std::vector<uint64_t> periods;
  for (uint64_t i = 1; i <= last; i = i < 16 ? i + 1 : std::max(i + 1, i * 109 / 100)) periods.push_back(i);
  if (periods.back() != last) periods.push_back(last);
  for (double fraction : {1.0, 0.5, 0.25, 0.125}) {
    if (fraction < min_fraction && fraction != 1.0) continue;
    for (uint64_t i : periods) {
      Prediction p = predict(time, {processors, i, fraction}, costs, scene);
      const double e = p.relative_error, b = best.prediction.relative_error;
      const bool tie = std::isfinite(b) && std::fabs(e - b) <= 1e-9 * b;
      if ((!tie && e < b) || (tie && (i > best.period || (i == best.period && fraction < best.fraction))))
        best = {i, fraction, p};
    }
  }
  return best;
}

}  // namespace sirad::model
