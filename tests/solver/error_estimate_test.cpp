// sirad tests: the run's own error estimate (solver/error_estimate.h) — batch means with doubling
// batches, and its calibration against the measured error of real runs (the reference solver).
#include <cmath>
#include <random>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "engine/shot.h"
#include "solver/error_estimate.h"
#include "solver/reference.h"
#include "tests/cluster_util.h"
#include "tests/test_util.h"
#include "util/error.h"

namespace sirad {
namespace {

TEST(BatchMeans, DoublesItsBatchesAndKeepsHalfToAllSlotsFull) {
  BatchMeans b(3, 8);
  std::vector<glm::dvec3> v(3, glm::dvec3(1.0));
  for (int k = 1; k <= 1000; ++k) {
    b.add(v);
    EXPECT_LE(b.full_batches(), 8);
    if (k >= 8) {
      EXPECT_GE(b.full_batches(), 4) << k;
    }
    EXPECT_EQ(static_cast<uint64_t>(b.full_batches()) * b.batch_size() <= static_cast<uint64_t>(k), true);
  }
  EXPECT_EQ(b.batch_size(), 128u);  // 1000 = 7 full batches of 128 and 104 in the eighth
  EXPECT_EQ(b.full_batches(), 7);
  EXPECT_THROW(BatchMeans(3, 5), Error);
}

TEST(BatchMeans, EstimatesTheErrorOfIndependentValues) {
  // Every patch gets values 1 + N(0, s^2), i.i.d.: the error of the mean of m values is s / sqrt(m)
  // per channel, so the relative error (all channels, all patches alike) is s / sqrt(m). With
  // 200 patches x 3 channels the estimate's own relative spread is about 1 / sqrt(2 * 600 * 15)
  // = 0.7 % (16 to 32 batches): 5 % is far outside chance, and a wrong factor (batch size,
  // sqrt(G)) would be far outside 5 %.
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 200});
  for (auto& m : mesh.materials) m.emission = glm::vec3(0.0f);  // every patch counts
  BatchMeans b(mesh.size());
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 0.3);
  std::vector<glm::dvec3> v(mesh.size());
  const int m = 3000;
  for (int k = 0; k < m; ++k) {
    for (auto& x : v) x = glm::dvec3(1.0 + noise(rng), 1.0 + noise(rng), 1.0 + noise(rng));
    b.add(v);
  }
  double expected = 0.3 / std::sqrt(static_cast<double>(b.full_batches()) * static_cast<double>(b.batch_size()));
  double got = b.relative_error(mesh);
  fmt::print("batch means: {} batches of {}, estimate {:.5f}, exact {:.5f}\n", b.full_batches(), b.batch_size(), got, expected);
  EXPECT_NEAR(got / expected, 1.0, 0.05);
}

// The solver's estimate against the error it really has: Cornell with the first shot, the
// measured relative RMS error per non-emitting patch against the reference with the
// reference's own variance subtracted (relative_rms_vs_reference). The issue asks for a
// factor of 1.5 either way. Both sides scatter: a run's errors are correlated across patches (one
// bundle's direction brightens or darkens whole walls together), so the measured error of one run
// has few effective degrees of freedom and scatters by some 10-20 % around its expectation; the
// estimate's batches see the same correlated modes. Checked at 256 and 1024 bundles, with one
// and a quarter shot per bundle, random directions (measured ratios 0.85 .. 1.19), and with the
// command line's default, stratified directions and shots (1.14, 1.17: batches shorter than a
// block of strata count the strata's negative correlation as noise, so a little pessimistic).
TEST(ErrorEstimate, IsCalibratedAgainstTheReference) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 1200});
  ReferenceSolution ref = solve_reference(mesh, {.rays_per_patch = 4096, .light_samples = 1024, .batches = 8, .seed = 3});
  auto engine = make_cl_engine(mesh);
  auto shots = make_cl_shot_engine(mesh);
  for (auto [x, directions] : {std::pair{1.0, Directions::random}, {0.25, Directions::random}, {0.25, Directions::stratified}}) {
    SolverOptions so{.seed = 17, .directions = directions};
    so.shots_per_bundle = x;
    so.track_error = true;
    Solver solver(mesh, *engine, so, shots.get());
    for (uint64_t k = 0; k < 1024; ++k) {
      solver.step(k);
      if (k + 1 == 256 || k + 1 == 1024) {
        ReferenceError measured = relative_rms_vs_reference(mesh, solver.estimate(), ref.radiosity, ref.radiosity_se);
        double estimate = solver.error_estimate();
        fmt::print("{}, shots per bundle {}, {} bundles: estimate {:.4f}, measured {:.4f} (raw {:.4f}), ratio {:.2f}\n",
                   to_string(directions), x, k + 1,
                   estimate, measured.corrected, measured.raw, estimate / measured.corrected);
        EXPECT_GT(estimate / measured.corrected, 1.0 / 1.5);
        EXPECT_LT(estimate / measured.corrected, 1.5);
      }
    }
  }
}

// The cluster's estimate: the nodes are independent chains and the result their count-weighted
// mean, so the coordinator combines the nodes' own batch-means estimates as
// sqrt(sum (m_p / M)^2 e_p^2), per chunk with the counts it holds (Aggregate::combined_error).
// Embedded clusters of 2 nodes with
// the first shot, exchanging every 64 bundles. One run's measured error scatters far more than
// the estimate (seeds 1-6 and 23 measured 0.015-0.027 around estimates of 0.020-0.022: the errors
// are correlated across patches), so the estimate is held against the RMS of the measured errors
// of 4 runs (the error the estimate predicts) and each run's estimate must be within 1.5 of it.
TEST(ErrorEstimate, ClusterIsCalibratedAgainstTheReference) {
  cluster::RunConfig c;
  c.scene = builtin_cornell();
  c.mesh_options.target_patches = 1200;
  c.bundles = 1536;
  c.exchange_every = 64;
  c.shots_per_bundle = 0.5;
  PatchMesh mesh = mesh_scene(c.scene, c.mesh_options);
  ReferenceSolution ref = solve_reference(mesh, {.rays_per_patch = 4096, .light_samples = 1024, .batches = 8, .seed = 3});
  double measured2 = 0.0;
  std::vector<double> estimates;
  for (uint64_t seed : {1, 2, 3, 4}) {
    c.seed = seed;
    cluster::Status last;
    c.status = [&](const cluster::Status& s) { last = s; };
    cluster::test::Outcome o = cluster::test::run_cluster(c, 2, fmt::format("inproc://error-estimate-{}", seed));
    ASSERT_EQ(o.mesh.hash, mesh.hash);
    double m = relative_rms_vs_reference(mesh, o.result.radiosity, ref.radiosity, ref.radiosity_se).corrected;
    fmt::print("cluster of 2, seed {}, {} bundles: estimate {:.4f}, measured {:.4f}\n", seed, o.result.bundles,
               last.error_estimate, m);
    measured2 += m * m / 4.0;
    estimates.push_back(last.error_estimate);
  }
  double measured = std::sqrt(measured2);
  for (double e : estimates) {
    EXPECT_GT(e / measured, 1.0 / 1.5);
    EXPECT_LT(e / measured, 1.5);
  }
}

}  // namespace
}  // namespace sirad
