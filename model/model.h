// sirad: the paper's cost and error model (seed paper, sections 2 to 5): what P processors that
// iterate independently and exchange a fraction S of their data every I iterations buy, for a
// scene of contraction a (the ratio of (k+1)-bounce to k-bounce energy) and first-bounce
// relative deviation sigma_1 / C. Pure functions of their arguments: no clocks, no sockets.
//
// Where the paper is inconsistent this follows its derivations, not its display:
//  - the effective sample number (its eq. 7 writes sum s(k) a^(2k)) is
//    E = sum_k s(k) a^(2(k-1)), the weighting its own recursion E' = P + (a^2 + 1) E and closed
//    form A (B^K - 1) / (B - 1) need (with a^(2k) every E is a^2 times smaller and the
//    recursion's constant term would be P a^2); the ranking of setups, and so the best I, is the
//    same either way;
//  - a combined step multiplies the paths it extends by c = 1 + (P - 1) S (combined_factor),
//    not by the P S of eq. 6: a node that takes the others' data for a fraction S of the patches
//    keeps its own for the rest, so per patch it extends its own paths there and P nodes' paths
//    on the fraction S. Both are P at S = 1 (the paper's figures 1, 2 and 4); for S < 1 / P
//    eq. 6 makes exchanging lose paths (P S < 1, fewer than an independent step's 1) and its
//    figure 3 error explode as S falls (7.7 at a = 0.9, S = 0.05, against 0.29 at S = 1);
//  - the closed form is derived for S = 1; with S the combined step is E' = P + (c a^2 + 1) E,
//    so B = (a^2 + 1)^(I-1) (c a^2 + 1) and A is unchanged.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace sirad::model {

// The measured costs: T_i one iteration (a bundle) on one processor, T_e one exchange of the
// whole state with one other processor (the paper's exchange costs P S T_e).
struct Costs {
  double t_iteration = 4.5;  // seconds (the paper's Origin 2000)
  double t_exchange = 0.05;
};

// P processors, an exchange every I iterations (0: never, only the final combination), a
// fraction S in (0, 1] of the data each time.
struct Setup {
  uint32_t processors = 8;
  uint64_t exchange_every = 1;
  double fraction = 1.0;
};

// The scene: contraction a in [0, 1) and sigma_1 / C > 0.
struct Scene {
  double contraction = 0.5;
  double sigma_ratio = 1.0;
};

// Throws sirad::Error naming the quantity for a setup, costs or scene outside its range.
void check(const Setup& setup);
void check(const Costs& costs);
void check(const Scene& scene);

// The combined step's factor on the paths it extends: 1 + (P - 1) S (see above; eq. 6: P S).
double combined_factor(uint32_t processors, double fraction);

// (1) T = N T_i + (N P S / I) T_e (no exchange cost when I = 0).
double total_time(uint64_t iterations, const Setup& setup, const Costs& costs);
// (2) N = T I / (T_i I + T_e P S), rounded down: the iterations that fit in `time`.
uint64_t iterations_in(double time, const Setup& setup, const Costs& costs);

// The sample numbers s(k), k = 1..N, after N iterations, as natural logarithms (they grow like
// binomial coefficients and overflow doubles beyond N ~ 1000; -inf for none). The run is
// phases of I iterations, each starting with a combined step (eqs. 5, 6: s(k+1) += c s(k))
// followed by I - 1 independent ones (eqs. 3, 4: s(k+1) += s(k)); every step adds P one-bounce
// samples. I = 0: all steps independent. max_bounces > 0 keeps only s(1..max_bounces): exact
// for them, since s(k) needs only s(1..k).
std::vector<double> log_sample_numbers(uint64_t iterations, const Setup& setup, uint64_t max_bounces = 0);

// Section 2: the relative error of a run with these sample numbers, bias plus three standard
// deviations:  a^(n+1) + 3 (1 - a) (sigma_1 / C) sqrt(sum_k a^(2(k-1)) / s(k)),  n = the longest
// path estimated: `longest`, or 0 for the number of sample numbers given (zeros among them,
// -inf, add nothing).
double relative_error(const std::vector<double>& log_samples, const Scene& scene, uint64_t longest = 0);

// The effective sample number E = sum_k s(k) a^(2(k-1)) from the sample numbers (log), and in
// closed form for `phases` whole phases (section 5): A (B^K - 1) / (B - 1) with
// A = P ((a^2 + 1)^I - 1) / a^2 and B = (a^2 + 1)^(I-1) (P S a^2 + 1) (limits taken at a = 0
// and B = 1). Both as natural logarithms (E overflows as easily as s(k)).
double log_effective_samples(const std::vector<double>& log_samples, double contraction);
double log_effective_samples_closed(uint64_t phases, const Setup& setup, double contraction);

// Everything the model says about one setup run for `time` seconds.
struct Prediction {
  uint64_t iterations = 0, phases = 0;  // N, K = N / I (0 when I = 0)
  double relative_error = 0;            // section 2, from the sample-number recursion (inf: N = 0)
  double log_effective = 0;             // ln E, from the recursion (-inf: N = 0)
  double bias = 0;                      // its bias part a^(N+1) (1 when N = 0)
  double sd = 0;                        // its relative standard deviation (the 3 sd part / 3)
};
Prediction predict(double time, const Setup& setup, const Costs& costs, const Scene& scene);

// The least time in which the setup's predicted error reaches `target` (the iterations N found
// by doubling and bisection, the error falling with N; then equation 1), or inf if not within max_iterations.
double time_to_error(double target, const Setup& setup, const Costs& costs, const Scene& scene,
                     uint64_t max_iterations = 1u << 20);

// The exchange period that maximises the effective sample number in `time` (the paper's goal
// function, section 5), over I = 1 .. max_period and at most the longest period with one whole
// phase in `time` (K(I) >= 1: the closed form assumes each phase runs its I steps): the
// continuous optimum of the closed form with K(I) = T / (T_i I + T_e P S) phases, found by
// golden-section search on ln E and then settled among the neighbouring whole periods.
// `brute_force_period` tries every I.
uint64_t best_period(double time, Setup setup, const Costs& costs, double contraction, uint64_t max_period);
uint64_t brute_force_period(double time, Setup setup, const Costs& costs, double contraction, uint64_t max_period);

// `--exchange-every auto`: the period I (1 .. max_period, and at most the iterations that fit
// in `time`) and fraction S (1, 1/2, 1/4, 1/8, not below min_fraction) whose predicted relative
// error (section 2, predict()) in `time` is the least; ties go to the longer period and then
// the smaller fraction (less traffic). The candidates for I are every period up to 16 and
// about 8 per octave beyond, so a few hundred predictions at most.
struct ExchangeChoice {
  uint64_t period = 1;
  double fraction = 1.0;
  Prediction prediction;
};
ExchangeChoice choose_exchange(double time, uint32_t processors, const Costs& costs, const Scene& scene,
                               uint64_t max_period, double min_fraction = 1.0 / 8);

}  // namespace sirad::model
