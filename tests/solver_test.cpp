// sirad tests: statistical behaviour of the stochastic iteration on the OpenCL engine.
// Every tolerance below is derived from the estimator's variance; the derivation sits beside
// the test. Seeds are fixed, so each test is deterministic; the bounds are wide enough (>= 4
// standard deviations, or a factor that the derivation justifies) to hold for any seed.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numeric>

#include <gtest/gtest.h>

#include "tests/test_util.h"

namespace sirad {
namespace {

using test::solve;

// Furnace, chain rule. Exact answer B = 2 (E = 1, rho = 0.5, closed).
//
// One bundle from the exact state gives, per patch j, X_j = 1 + rho * 2 * c_j with
// c_j = 2 delta n_j / A_j (n_j: lines crossing j; every front neighbour is a wall at B = 2).
// E[c_j] = 1. Given the direction, E[n_j | w] = A_j |cos theta_j| / delta, so
// Var(c_j) = Var(2 |cos theta|) + (2 delta / A_j)^2 E Var(n_j | w) = 1/3 + v_lat, since
// |cos theta| is uniform on [0, 1] for w uniform on the sphere. The lattice term is at most
// the Poisson value 2 delta / A_j = 1 / E[n_j] (a jittered lattice counts no more erratically
// than Poisson points); the auto grid aims at E[n_j] ~ 4, so we take v_lat <= 1/2 as a margin.
// sigma^2 = Var(X_j) = (2 rho)^2 Var(c_j) in [1/3, 5/6].
// The chain passes errors on with factor rho in expectation, with positive correlation, so the
// variance of the M-bundle mean lies between sigma^2 / M and sigma^2 / M * (1 + rho)/(1 - rho).
// Relative RMS per patch = sqrt(Var) / 2:
//   lower  sqrt((1/3) / 1024) / 2 = 0.0090,   upper sqrt((5/6) * 3 / 1024) / 2 = 0.0247.
// The area-weighted mean: the cube's projected area is s^2 (|wx| + |wy| + |wz|), so the mean
// of X over the walls is 1 + 2 rho (2/3) sum |w_i|; with E|w_x w_y| = 2/(3 pi) on the sphere,
// Var(sum |w_i|) = 1 + 6 * 2/(3 pi) - 1.5^2 = 0.0232, std of the mean per bundle 0.102, after
// 1024 bundles with correlation time 3: 0.102 * sqrt(3/1024) = 0.0055 (0.28 %), so 1 % is 3.6
// standard deviations: the bound.
TEST(SolverFurnace, ChainIsUnbiasedWithDerivedPerPatchError) {
  PatchMesh mesh = mesh_scene(builtin_furnace(), {.target_patches = 768});
  auto engine = make_cl_engine(mesh);
  Solver s = solve(mesh, *engine, {.seed = 11}, 1024);
  auto est = s.estimate();
  double mean = area_mean(mesh, est);
  EXPECT_NEAR(mean, 2.0, 0.02) << "area-weighted mean after 1024 bundles";
  double sq = 0.0, a = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    double d = est[j].x - 2.0;
    sq += mesh.area[j] * d * d;
    a += mesh.area[j];
  }
  double rel_rms = std::sqrt(sq / a) / 2.0;
  std::printf("furnace chain, 1024 bundles: mean %.5f, relative RMS per patch %.5f\n", mean, rel_rms);
  EXPECT_GT(rel_rms, 0.0090 * 0.8) << "too little noise: the estimator is not drawing lines";
  EXPECT_LT(rel_rms, 0.0247) << "per-patch error above the derived bound";
}

// Furnace, average rule (the paper's). In expectation L'(m) = E + T L(m-1), so the error of
// the expected average obeys e_m = (I - (I - T)/m) e_(m-1). In the furnace the constant vector
// is an eigenvector of T with eigenvalue rho, and e_0 = E - B = -1, hence exactly
//   E[mean L(m)] - 2 = -prod_(k=1..m) (1 - (1 - rho)/k)   ~   -m^-(1 - rho) / Gamma(rho).
// We average R = 12 independent runs and fit the log-log slope of the bias between m = 32 and
// m = 1024 (6 points). The per-run noise of the mean at m bundles is about 0.1/sqrt(m) (see the
// chain test), against a bias of 0.56/sqrt(m): over 12 runs the relative error of each bias
// point is ~ 0.1/0.56/sqrt(12) = 5 %, so the slope (over a factor 32 in m) is known to about
// 0.05 / ln(32) * sqrt(2) = 0.02; we allow 0.06 (3 standard deviations) around the exact
// product's slope, and 10 % on each bias value against the exact product.
TEST(SolverFurnace, AverageRuleBiasFollowsPowerLaw) {
  PatchMesh mesh = mesh_scene(builtin_furnace(), {.target_patches = 48});
  auto engine = make_cl_engine(mesh);
  const double rho = 0.5;
  const std::vector<uint64_t> checkpoints = {32, 64, 128, 256, 512, 1024};
  std::vector<double> bias(checkpoints.size(), 0.0);
  const int runs = 12;
  for (int r = 0; r < runs; ++r) {
    Solver s(mesh, *engine, {.seed = 100 + static_cast<uint64_t>(r), .grid = 24, .rule = UpdateRule::average});
    std::size_t next = 0;
    for (uint64_t k = 0; k < checkpoints.back(); ++k) {
      s.step(k);
      if (s.bundles() == checkpoints[next]) bias[next++] += (area_mean(mesh, s.estimate()) - 2.0) / runs;
    }
  }
  std::vector<double> x, y, exact;
  for (std::size_t i = 0; i < checkpoints.size(); ++i) {
    double prod = 1.0;
    for (uint64_t k = 1; k <= checkpoints[i]; ++k) prod *= 1.0 - (1.0 - rho) / k;
    exact.push_back(-prod);
    ASSERT_LT(bias[i], 0.0) << "the average rule must be biased low at m = " << checkpoints[i];
    EXPECT_NEAR(bias[i], exact.back(), 0.10 * std::fabs(exact.back())) << "m = " << checkpoints[i];
    x.push_back(std::log(static_cast<double>(checkpoints[i])));
    y.push_back(std::log(-bias[i]));
  }
  auto slope = [&](const std::vector<double>& yy) {
    double mx = std::accumulate(x.begin(), x.end(), 0.0) / x.size();
    double my = std::accumulate(yy.begin(), yy.end(), 0.0) / yy.size();
    double sxy = 0, sxx = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      sxy += (x[i] - mx) * (yy[i] - my);
      sxx += (x[i] - mx) * (x[i] - mx);
    }
    return sxy / sxx;
  };
  std::vector<double> y_exact;
  for (double e : exact) y_exact.push_back(std::log(-e));
  double fitted = slope(y), predicted = slope(y_exact);
  std::printf("average rule: bias exponent fitted %.4f, exact product %.4f; bias at 1024: %.5f (exact %.5f)\n",
              fitted, predicted, bias.back(), exact.back());
  EXPECT_NEAR(predicted, -(1.0 - rho), 0.01);
  EXPECT_NEAR(fitted, predicted, 0.06) << "fitted bias exponent";
}

// Energy balance in a closed scene with uniform rho: for the exact solution
// sum A (B - E) = rho sum A B. For one chain step from state L = L'(m-1) the kernel's estimate
// satisfies E[sum_j A_j (L'_j(m) - E_j) / rho | L] = sum_j A_j L_j exactly when the transport
// is unbiased in a closed scene, so X_m = sum A (L'(m) - E)/rho - sum A L'(m-1) is a martingale
// difference: mean 0, uncorrelated across m. With M = 512 steps the mean of X divided by its
// standard error is approximately standard normal; |t| < 4.5 fails by chance with p < 1e-5.
// A transport biased by even 1 % (a wrong factor, lost crossings, back faces gathered) moves
// t by about 0.01 * sum A L / (sd(X)/sqrt(M)), dozens of standard errors here.
// Finally the solution itself: its imbalance equals rho * mean(X) plus the telescoping term
// rho * sum A (L'(0) - L'(M)) / M, which the test checks to float precision.
TEST(SolverEnergy, ClosedRoomBalancesEmissionAndReflection) {
  const float rho = 0.6f;
  PatchMesh mesh = mesh_scene(test::closed_room(rho), {.target_patches = 1500});
  auto engine = make_cl_engine(mesh);
  Solver s(mesh, *engine, {.seed = 5});
  auto weighted = [&](const std::vector<glm::dvec3>& v, bool minus_e) {
    double t = 0.0;
    for (std::size_t j = 0; j < mesh.size(); ++j)
      t += mesh.area[j] * (v[j].x - (minus_e ? mesh.emission(j).x : 0.0));
    return t;
  };
  const int M = 512;
  std::vector<double> xs;
  auto first_state = s.state();
  for (int m = 0; m < M; ++m) {
    double before = weighted(s.state(), false);
    s.step(static_cast<uint64_t>(m));
    xs.push_back(weighted(s.state(), true) / rho - before);
  }
  double mean = std::accumulate(xs.begin(), xs.end(), 0.0) / M;
  double var = 0.0;
  for (double v : xs) var += (v - mean) * (v - mean);
  double se = std::sqrt(var / (M - 1) / M);
  std::printf("closed room: energy martingale mean %.4g, standard error %.4g (t = %.2f)\n", mean, se, mean / se);
  EXPECT_LT(std::fabs(mean / se), 4.5) << "mean " << mean << " standard error " << se;
  EXPECT_GT(se, 0.0);

  std::vector<glm::dvec3> avg(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) avg[j] = s.sum()[j] / static_cast<double>(M);
  double lhs = weighted(avg, true), rhs = rho * weighted(avg, false);
  double telescoping = rho * (weighted(first_state, false) - weighted(s.state(), false)) / M;
  EXPECT_NEAR(lhs - rhs, rho * mean + telescoping, 1e-6 * rhs);
  EXPECT_LT(std::fabs(lhs - rhs), 4.5 * rho * se + std::fabs(telescoping) + 1e-6 * rhs);
}

// Same seed, device and settings: bitwise identical estimates; another seed differs.
TEST(SolverDeterminism, SameSeedSameBits) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 600});
  auto engine = make_cl_engine(mesh);
  auto a = solve(mesh, *engine, {.seed = 9}, 40).sum();
  auto b = solve(mesh, *engine, {.seed = 9}, 40).sum();
  auto c = solve(mesh, *engine, {.seed = 10}, 40).sum();
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(a[0])));
  EXPECT_NE(0, std::memcmp(a.data(), c.data(), a.size() * sizeof(a[0])));
}

// Convergence: the relative RMS difference D(m) of two independent runs falls as 1/sqrt(m).
// D(m)^2 is an area-weighted sum of per-patch squared differences; with independent runs its
// expectation is 2 Var(estimate at m) ~ 2 sigma^2 tau / m (tau: the chain's correlation time),
// so log D falls with slope -1/2. We pool 3 pairs (D^2 averaged over the pairs, then the log).
// Its fluctuation: the patches share directions, so D(m)^2 behaves like a mean of about m
// independent direction draws; with the small light's rare, heavy-tailed hits we take the
// relative standard deviation of D^2 as ~1/sqrt(m/8) per pair (8x the Gaussian value), i.e.
// 0.2 at m = 64 and 0.05 at m = 1024 after pooling 3 pairs, hence a standard error of the
// slope of sqrt(0.2^2 + 0.05^2) / 2 / ln 16 = 0.037. We allow 0.1 (2.7 standard errors).
// A transport that does not average out (a constant bias between the runs, or estimates that
// do not depend on the bundle) gives slope ~0; an accumulation error that grows gives > 0.
TEST(SolverConvergence, CornellDifferenceFallsAsInverseSqrt) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 1000});
  auto engine = make_cl_engine(mesh);
  double d64 = 0, d1024 = 0;
  const int pairs = 3;
  for (int p = 0; p < pairs; ++p) {
    Solver a(mesh, *engine, {.seed = 1000 + 2 * static_cast<uint64_t>(p)});
    Solver b(mesh, *engine, {.seed = 1001 + 2 * static_cast<uint64_t>(p)});
    for (uint64_t k = 0; k < 1024; ++k) {
      a.step(k);
      b.step(k);
      if (k + 1 == 64) d64 += std::pow(relative_rms(mesh, a.estimate(), b.estimate()), 2) / pairs;
    }
    d1024 += std::pow(relative_rms(mesh, a.estimate(), b.estimate()), 2) / pairs;
  }
  double slope = 0.5 * (std::log(d1024) - std::log(d64)) / std::log(16.0);
  std::printf("cornell: relative RMS difference %.4f at 64 bundles, %.4f at 1024: slope %.3f\n", std::sqrt(d64),
              std::sqrt(d1024), slope);
  EXPECT_NEAR(slope, -0.5, 0.1);
}

}  // namespace
}  // namespace sirad
