// sirad tests: what an honest node's state of a chunk can be (cluster/plausibility.h), on
// synthetic chains whose law is known, and through the policy.
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "cluster/plausibility.h"
#include "cluster/policy.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "util/error.h"

namespace sirad::cluster {
namespace {

// A node's chain as the tests below model it: per bundle one value per channel (the chunk's
// area-weighted mean estimate), reported as running sums after grants of random sizes.
//   ar1: mean mu + AR(1) noise of lag-one correlation r and marginal sd sigma (a chain's
//        memory: what batch means must outlast);
//   spiky: 0, or h with probability q per bundle (a small chunk hit by one line now and then:
//        mean q h, the heavy tail a Gaussian test would take for a lie).
struct Chain {
  enum Kind { ar1, spiky } kind = ar1;
  double mu = 2, sigma = 1, r = 0.5, q = 0, h = 0;
  double scale = 1, bias = 0;  // a liar: every value times scale, plus bias
  std::mt19937_64 rng;
  double e = 0;
  double s = 0;
  uint64_t count = 0;
  double next() {
    double x;
    if (kind == ar1) {
      e = r * e + std::sqrt(1 - r * r) * sigma * std::normal_distribution<double>()(rng);
      x = mu + e;
    } else {
      x = std::bernoulli_distribution(q)(rng) ? h : 0.0;
    }
    return scale * x + bias;
  }
  Plausibility::Observation run(uint64_t bundles) {
    for (uint64_t i = 0; i < bundles; ++i) s += next();
    count += bundles;
    return {glm::dvec3(s), count};
  }
};

std::vector<uint32_t> one_chunk() { return {0, 1}; }

ChunkBounds bounds(double low, double high) {
  return {{1.0}, {glm::dvec3(low)}, {glm::dvec3(high)}};
}

// The batch length the policy would use for a chain of memory r (chain_memory's rule).
uint64_t memory_of(double r) { return static_cast<uint64_t>(std::ceil(std::log(1e-2) / std::log(r))); }

struct Outcome {
  double worst = 0;     // the largest honest score seen
  int alarms = 0;       // honest states called implausible
  int64_t caught = -1;  // the liar's bundles when it was caught (-1: never)
};

// `nodes` chains (the last one lying when liar.scale != 1 or liar.bias != 0) report after
// grants of 1..max_grant bundles, in turns, until each has about `bundles`; every state is
// assessed before it is taken, as the policy does.
Outcome simulate(std::vector<Chain> chains, uint64_t bundles, uint64_t max_grant, uint64_t batch, ChunkBounds b,
                 uint64_t seed) {
  Plausibility plausible(one_chunk(), std::move(b), batch, true);
  for (std::size_t i = 0; i < chains.size(); ++i) plausible.add_node();
  std::mt19937_64 rng(seed);
  Outcome out;
  const std::size_t liar = chains.back().scale != 1 || chains.back().bias != 0 ? chains.size() - 1 : chains.size();
  bool going = true;
  while (going) {
    going = false;
    for (std::size_t i = 0; i < chains.size(); ++i) {
      if (chains[i].count >= bundles) continue;
      going = true;
      const uint64_t g = std::uniform_int_distribution<uint64_t>(1, max_grant)(rng);
      Plausibility::Observation o = chains[i].run(g);
      Plausibility::Verdict v = plausible.assess(static_cast<uint32_t>(i), 0, o);
      if (i == liar) {
        if (v.score > 1 && out.caught < 0) out.caught = static_cast<int64_t>(o.count);
      } else {
        out.worst = std::max(out.worst, v.score);
        out.alarms += v.score > 1;
      }
      plausible.take(static_cast<uint32_t>(i), 0, o);
    }
  }
  return out;
}

std::vector<Chain> honest_ar1(int n, double r, uint64_t seed, double mu = 2, double sigma = 1) {
  std::vector<Chain> c(n);
  for (int i = 0; i < n; ++i) {
    c[i].mu = mu, c[i].sigma = sigma, c[i].r = r;
    c[i].rng.seed(seed * 1000 + i);
  }
  return c;
}

// The delete-a-batch jackknife of equal batches is the spread of their means over k; with
// one large value in a batch it is about the square of what that value does to the mean.
TEST(Plausibility, JackknifeOfEqualBatchesIsTheSpreadOfTheirMeans) {
  std::vector<Plausibility::Batch> b = {{4, glm::dvec3(4.0)}, {4, glm::dvec3(8.0)}, {4, glm::dvec3(12.0)}, {4, glm::dvec3(0.0)}};
  // batch means 1, 2, 3, 0: mean 1.5, sample variance (0.25 + 0.25 + 2.25 + 2.25) / 3 = 5/3.
  EXPECT_NEAR(Plausibility::jackknife_variance(b).x, (5.0 / 3.0) / 4.0, 1e-12);
  // A spike h in the first of a long and a short batch: the mean moves by h / m, and the
  // jackknife sees y without it (0) and y with it alone (h / n1): sd h / (2 n1), so the spike
  // is at most 2 n1 / m <= 2 of its own standard errors away from 0.
  std::vector<Plausibility::Batch> spike = {{1000, glm::dvec3(50.0)}, {3, glm::dvec3(0.0)}};
  const double y = 50.0 / 1003, se = std::sqrt(Plausibility::jackknife_variance(spike).x);
  EXPECT_NEAR(se, 50.0 / (2 * 1000), 1e-12);
  EXPECT_LE(y / se, 2.0);
  EXPECT_EQ(Plausibility::jackknife_variance({{5, glm::dvec3(1.0)}}).x, 0.0);
}

// What the scene allows: on the furnace (E = 1, rho = 0.5 everywhere) exactly B = 2 above and
// E = 1 below; a channel whose largest reflectance is 1 has no upper bound; the background
// counts as a source.
TEST(Plausibility, ChunkBoundsFollowEmissionAndReflectance) {
  PatchMesh furnace = mesh_scene(builtin_furnace(), {.target_patches = 300});
  std::vector<uint32_t> starts = chunk_starts(static_cast<uint32_t>(furnace.size()), 4);
  ChunkBounds b = chunk_bounds(furnace, starts);
  for (std::size_t c = 0; c < 4; ++c)
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(b.low[c][k], 1.0, 1e-6);
      EXPECT_NEAR(b.high[c][k], 2.0, 1e-6);
    }
  double total = 0;
  for (uint32_t j = starts[0]; j < starts[1]; ++j) total += b.weight[j];
  EXPECT_NEAR(total, 1.0, 1e-9);
  PatchMesh white = furnace;
  white.materials[0].reflectance.y = 1.0f;
  ChunkBounds w = chunk_bounds(white, starts);
  EXPECT_TRUE(std::isinf(w.high[0].y));
  EXPECT_NEAR(w.high[0].x, 2.0, 1e-6);
  PatchMesh lit = furnace;
  lit.background = glm::vec3(10.0f);  // gathered at most max(2, 1 + 0.5 * 10, 10) = 10
  EXPECT_NEAR(chunk_bounds(lit, starts).high[0].x, 1.0 + 0.5 * 10.0, 1e-6);
  EXPECT_EQ(chain_memory(furnace, 0), 7u);        // 0.5^7 < 0.01
  EXPECT_EQ(chain_memory(furnace, 0.125), 32u);   // 4 / X
  EXPECT_EQ(chain_memory(white, 0), 1024u);
}

// Honest chains are never called implausible, and the largest score they reach stays well
// below the threshold, as the derivation in plausibility.h says: 3 to 8 nodes of AR(1) chains
// of memory 0.5 and 0.9 (batches of chain_memory), grants of 1 to 64 bundles, 4000 bundles
// each, with the scene's bound the exact answer (mu = high, the furnace's case), 20 seeds:
// about 10^5 assessments. Their worst score, measured: see the printout (a t of 15 degrees of
// freedom exceeds 6 once in 4 10^5, which is a score of 6 / 12 = 0.5 under the largest f).
TEST(Plausibility, HonestChainsAreNeverCalledImplausible) {
  double worst = 0;
  for (double r : {0.5, 0.9})
    for (int nodes : {3, 5, 8})
      for (uint64_t seed = 1; seed <= 20; ++seed) {
        Outcome o = simulate(honest_ar1(nodes, r, seed), 4000, 64, memory_of(r), bounds(1.0, 2.0), seed);
        EXPECT_EQ(o.alarms, 0) << "r " << r << " nodes " << nodes << " seed " << seed;
        worst = std::max(worst, o.worst);
      }
  std::printf("worst honest score %.3f\n", worst);
  EXPECT_LT(worst, 0.75);
}

// A node that joins late (a restart, a rejoin) beside mature chains: a young chain's noise
// per bundle is above theirs (its control variate's constant has learnt from few steps; here
// 10 times the sd, and a longer memory, r 0.9, which the batches outlast), and the references'
// variance per bundle over its few bundles does not cover it. It is not compared before it has
// kMinBatches batches of its own, whose jackknife shows its noise: never an alarm. (Compared
// from its second batch, as before, 14 of these 40 young chains were called liars; in the
// emulated rejoin test, one run in three quarantined the rejoined node after its second report
// of 8 bundles, 30 of the references' standard errors from the median.)
TEST(Plausibility, ALateJoinerIsJudgedByItsOwnNoiseOnceItHasBatches) {
  for (uint64_t seed = 1; seed <= 40; ++seed) {
    Plausibility plausible(one_chunk(), bounds(1.0, 3.0), memory_of(0.9), true);
    std::vector<Chain> c = honest_ar1(2, 0.5, seed, 2.0, 0.05);
    Chain young;
    young.mu = 2, young.sigma = 0.5, young.r = 0.9;
    young.rng.seed(seed * 31 + 7);
    young.e = young.sigma * std::normal_distribution<double>()(young.rng);  // its youth's error, already there
    for (int i = 0; i < 3; ++i) plausible.add_node();
    for (int round = 0; round < 500; ++round)
      for (uint32_t i = 0; i < 2; ++i) {
        Plausibility::Observation o = c[i].run(8);
        EXPECT_LE(plausible.assess(i, 0, o).score, 1.0);
        plausible.take(i, 0, o);
      }
    for (int round = 0; round < 120; ++round) {
      Plausibility::Observation o = young.run(8);
      Plausibility::Verdict v = plausible.assess(2, 0, o);
      EXPECT_TRUE(v.why.empty()) << "seed " << seed << " after " << o.count << " bundles: " << v.why;
      plausible.take(2, 0, o);
    }
  }
}

// Rare large estimates (0 or h with probability q per bundle) are not lies: a node's own
// jackknife widens with each one it has, so even with the scene's bound at the exact mean, and
// nodes that have seen none, nobody is called implausible.
TEST(Plausibility, RareLargeEstimatesAreNotLies) {
  for (double q : {1e-4, 1e-3, 1e-2, 0.1})
    for (uint64_t seed = 1; seed <= 10; ++seed) {
      std::vector<Chain> c(4);
      for (int i = 0; i < 4; ++i) {
        c[i].kind = Chain::spiky, c[i].q = q, c[i].h = 1.0 / q;  // mean 1
        c[i].rng.seed(seed * 77 + i);
      }
      Outcome o = simulate(c, 3000, 64, 7, bounds(0.0, 1.0), seed);
      EXPECT_EQ(o.alarms, 0) << "q " << q << " seed " << seed << " worst " << o.worst;
    }
}

// Liars among honest nodes are caught once the references have their batches: a node that
// multiplies its sums by 1000 or 3e38 or sends zeros (beyond the furnace's bounds as well) is
// caught within its first 1000 bundles; one that takes 10 % off, within the bounds, once
// 12 sqrt(2 v / m) + 0.01 * 2 < 0.2 with v = 0.3^2 (1 + r) / (1 - r) = 0.27 per bundle: after
// about 2400 bundles, caught here within 8000. With two nodes the scene's bound alone catches
// 1000x and zeros but not 10 % less (no median of two can say which node lies).
TEST(Plausibility, LiarsAreCaught) {
  struct Case {
    const char* name;
    double scale, bias;
    int nodes;
    int64_t caught_by;  // -1: never
  };
  for (const Case& k : {Case{"x1000", 1000, 0, 3, 1000}, Case{"x3e38", 3e38, 0, 3, 1000}, Case{"zero", 0, 0, 3, 1000},
                        Case{"-10%", 1, -0.2, 3, 8000}, Case{"x1000 of two", 1000, 0, 2, 1000},
                        Case{"zero of two", 0, 0, 2, 1000}, Case{"-10% of two", 1, -0.2, 2, -1}})
    for (uint64_t seed = 1; seed <= 5; ++seed) {
      SCOPED_TRACE(k.name);
      std::vector<Chain> c = honest_ar1(k.nodes, 0.5, seed, 2.0, 0.3);
      c.back().scale = k.scale, c.back().bias = k.bias;
      Outcome o = simulate(c, 8000, 16, 7, bounds(1.0, 2.0), seed);
      EXPECT_EQ(o.alarms, 0);
      if (k.caught_by > 0) {
        EXPECT_GT(o.caught, 0) << "seed " << seed;
        EXPECT_LE(o.caught, k.caught_by) << "seed " << seed;
      } else {
        EXPECT_EQ(o.caught, -1) << "seed " << seed;
      }
    }
}

// Through the policy: a node whose reports carry 0.8 times the honest sums (1.6, within the
// scene's bounds [1, 2]) is quarantined by the median once it and the others have their
// batches (12 sqrt(2 v / m) + 0.02 * 2 < 0.4 with v = 0.27 per bundle: after about 600
// bundles); its bundles go back and its data leave the estimate, and the honest nodes are not
// touched.
TEST(Plausibility, ThePolicyQuarantinesALiar) {
  PolicyConfig cfg{.bundles = 30000, .exchange_every = 8, .mode = Mode::async, .min_nodes = 3, .balance = false,
                   .batch_bundles = 7};
  Policy p(cfg, chunk_starts(1, 1), std::vector<double>(1, 1.0), bounds(1.0, 2.0));
  for (uint32_t n = 0; n < 3; ++n) {
    p.join();
    p.ready(n);
  }
  std::vector<Chain> c = honest_ar1(3, 0.5, 3, 2.0, 0.3);
  c[2].scale = 0.8;
  bool caught = false;
  for (int round = 0; round < 200 && !caught; ++round) {
    Orders o = p.next_work();
    for (const GrantOrder& g : o.grants) {
      if (p.node(g.node).dead) continue;
      uint64_t bundles = 0;
      for (const Range& r : g.ranges) bundles += r.size();
      Plausibility::Observation st = c[g.node].run(bundles);
      ChunkState s{0, {st.s.x, st.s.y, st.s.z}, st.count};
      try {
        p.take_result(g.node, g.id, g.ranges, {s}, 0.0);
      } catch (const Error& e) {
        EXPECT_EQ(g.node, 2u) << e.what();
        EXPECT_NE(std::string(e.what()).find("median of 3 nodes"), std::string::npos) << e.what();
        caught = true;
      }
    }
  }
  ASSERT_TRUE(caught);
  EXPECT_TRUE(p.node(2).quarantined);
  EXPECT_FALSE(p.node(0).dead);
  EXPECT_FALSE(p.node(1).dead);
  EXPECT_EQ(p.ledger().done_by(2).size(), 0u);
  EXPECT_NEAR(p.radiosity()[0].x, 2.0, 0.05);
}

// A node's error estimate is its own word: one that claims 1e-9 counts as no less than half
// the nodes' median error per bundle, so the run's estimate stays near the honest one.
TEST(Plausibility, AClaimedTinyErrorCannotEndARunEarly) {
  PolicyConfig cfg{.bundles = 3000, .exchange_every = 100, .mode = Mode::async, .min_nodes = 3, .balance = false};
  auto run = [&](double third) {
    Policy p(cfg, chunk_starts(1, 1), std::vector<double>(1, 1.0));
    for (uint32_t n = 0; n < 3; ++n) {
      p.join();
      p.ready(n);
    }
    Orders o = p.next_work();
    for (const GrantOrder& g : o.grants) {
      if (p.node(g.node).grants.front() != g.id) continue;
      ChunkState s{0, {200.0, 200.0, 200.0}, 100};
      p.take_result(g.node, g.id, g.ranges, {s}, g.node == 2 ? third : 0.01);
    }
    return p.error_estimate();
  };
  const double honest = run(0.01), lying = run(1e-9);
  EXPECT_GT(honest, 0);
  // Each node holds a third of the count: V = sum (1/3)^2 e_p^2 ... ; with the liar at half
  // the median: sqrt((0.01^2 + 0.01^2 + 0.005^2) / 9) against sqrt(3 0.01^2 / 9).
  EXPECT_NEAR(lying / honest, std::sqrt((2 + 0.25) / 3.0), 1e-6);
}

}  // namespace
}  // namespace sirad::cluster
