// sirad tests: the coordinator's plain-state bookkeeping: the bundle ledger, chunked per-node
// states with the count-weighted estimate, star and ring aggregates, the exchange rotation.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>

#include <gtest/gtest.h>

#include "cluster/exchange.h"
#include "cluster/result.h"
#include "util/check.h"
#include "util/error.h"

namespace sirad::cluster {
namespace {

// Three nodes take grants of different sizes until the budget is gone, one dies half-way and
// its grant is given again: every index 0..K-1 is done exactly once.
// The downloadable ledger.csv names nodes as nodes name themselves: a name a spreadsheet would
// run as a formula is led by a ' (shown as text), quotes are doubled, other names are as they
// are.
TEST(ClusterLedger, TheLedgersCsvRunsNoNodesNameAsAFormula) {
  RunResult r;
  for (const char* name : {"=HYPERLINK(\"http://x\")", "+1", "-2", "@SUM(A1)", "\tx", "a\"b", "gpu-box"})
    r.ledger.push_back({3, name, {0, 4}});
  EXPECT_EQ(ledger_csv(r), "node,name,first,last\n"
                           "3,\"'=HYPERLINK(\"\"http://x\"\")\",0,4\n"
                           "3,\"'+1\",0,4\n"
                           "3,\"'-2\",0,4\n"
                           "3,\"'@SUM(A1)\",0,4\n"
                           "3,\"'\tx\",0,4\n"
                           "3,\"a\"\"b\",0,4\n"
                           "3,\"gpu-box\",0,4\n");
}

TEST(ClusterLedger, EveryIndexOnceAcrossNodesAndAbandonedGrants) {
  const uint64_t K = 1000;
  Ledger ledger(K);
  std::vector<int> done(K, 0);
  auto finish = [&](uint32_t node, const std::vector<Range>& ranges) {
    for (const Range& r : ranges) {
      ledger.done(node, r);
      for (uint64_t k = r.first; k < r.last; ++k) ++done[k];
    }
  };
  auto lost = ledger.grant(2, 64);  // node 2 dies with this grant
  ASSERT_EQ(ledger.outstanding(2), 64u);
  for (int round = 0; !ledger.finished(); ++round) {
    finish(0, ledger.grant(0, 37));
    finish(1, ledger.grant(1, 5));
    if (round == 3) ledger.abandon(2);
    ASSERT_LT(round, 1000);
  }
  EXPECT_EQ(ledger.outstanding(2), 0u);
  EXPECT_EQ(ledger.done_count(), K);
  for (uint64_t k = 0; k < K; ++k) ASSERT_EQ(done[k], 1) << "index " << k;
  EXPECT_TRUE(ledger.grant(0, 10).empty());
}

// One index granted out of the middle of the free ranges: only a free one, once; the rest
// stays free around it, in order.
TEST(ClusterLedger, GrantsOneFreeIndexByItsNumber) {
  Ledger l(10);
  EXPECT_TRUE(l.grant_index(1, 4));
  EXPECT_FALSE(l.grant_index(2, 4));   // granted
  EXPECT_FALSE(l.grant_index(2, 10));  // beyond the budget
  EXPECT_EQ(l.available(), 9u);
  EXPECT_EQ(l.grant(2, 5), (std::vector<Range>{{0, 4}, {5, 6}}));
  l.done(1, {4, 5});
  EXPECT_FALSE(l.grant_index(3, 4));  // done
  EXPECT_TRUE(l.grant_index(3, 9));
  EXPECT_TRUE(l.grant_index(3, 6));
  EXPECT_EQ(l.grant(2, 10), (std::vector<Range>{{7, 9}}));
  EXPECT_EQ(l.available(), 0u);
  l.abandon(3);
  EXPECT_EQ(l.grant(4, 10), (std::vector<Range>{{6, 7}, {9, 10}}));
}

TEST(ClusterLedger, RefusesWhatWasNotGrantedOrIsDoneAlready) {
  Ledger ledger(100);
  auto g = ledger.grant(0, 10);
  ASSERT_EQ(g.size(), 1u);
  EXPECT_EQ(g[0], (Range{0, 10}));
  EXPECT_THROW(ledger.done(1, {0, 5}), Error);    // not node 1's
  EXPECT_THROW(ledger.done(0, {5, 15}), Error);   // beyond the grant
  ledger.done(0, {0, 5});
  EXPECT_THROW(ledger.done(0, {0, 5}), Error);    // counted twice
  EXPECT_THROW(ledger.done(0, {7, 7}), Error);    // empty
  ledger.abandon(0);
  EXPECT_THROW(ledger.done(0, {5, 10}), Error);   // a late report for a grant given away
  auto again = ledger.grant(1, 100);
  ASSERT_FALSE(again.empty());
  EXPECT_EQ(again[0], (Range{5, 100}));           // lowest indices first, merged
  EXPECT_EQ(ledger.done_count(), 5u);
}

// The ledger records who ran what; revoking a node returns its done and outstanding indices to
// the budget (a quarantined node), and they are granted again, lowest first.
TEST(ClusterLedger, RevokeReturnsDoneAndOutstandingIndices) {
  Ledger ledger(100);
  ledger.grant(0, 10);  // [0, 10)
  ledger.grant(1, 10);  // [10, 20)
  ledger.grant(0, 10);  // [20, 30)
  ledger.done(0, {0, 4});
  ledger.done(0, {4, 10});
  ledger.done(1, {10, 20});
  ledger.done(0, {20, 25});
  EXPECT_EQ(ledger.done_by(0), (std::vector<Range>{{0, 10}, {20, 25}}));
  EXPECT_EQ(ledger.done_by(1), (std::vector<Range>{{10, 20}}));
  EXPECT_EQ(ledger.revoke(0), 15u);
  EXPECT_EQ(ledger.done_count(), 10u);
  EXPECT_TRUE(ledger.done_by(0).empty());
  EXPECT_EQ(ledger.outstanding(0), 0u);
  EXPECT_EQ(ledger.available(), 90u);
  EXPECT_EQ(ledger.grant(2, 12), (std::vector<Range>{{0, 10}, {20, 22}}));
  EXPECT_THROW(ledger.done(0, {25, 30}), Error);  // its late report
}

// A node that dies holding indices loses them (Ledger::lose): each counts a loss by the node's
// identity however the ranges were cut since, one identity once, and poisoned(k) names the
// first indices lost by k identities or more, merged; abandon() (a planned disconnect) counts
// none. Lost indices are free again.
TEST(ClusterLedger, IndicesLostWithNodesAreCounted) {
  Ledger ledger(100);
  ledger.grant(0, 10);  // [0, 10)
  ledger.lose(0, "a");
  EXPECT_FALSE(ledger.poisoned(2));
  EXPECT_EQ(ledger.grant(1, 16), (std::vector<Range>{{0, 16}}));
  ledger.lose(1, "a");  // the same peer again: nothing more
  EXPECT_FALSE(ledger.poisoned(2));
  EXPECT_EQ(ledger.grant(1, 16), (std::vector<Range>{{0, 16}}));
  ledger.lose(1, "b");  // [0, 10) by a and b, [10, 16) by a and b
  EXPECT_EQ(ledger.poisoned(2), (Range{0, 16}));
  EXPECT_FALSE(ledger.poisoned(3));
  EXPECT_EQ(ledger.grant(2, 4), (std::vector<Range>{{0, 4}}));
  EXPECT_EQ(ledger.grant(3, 8), (std::vector<Range>{{4, 12}}));
  ledger.abandon(2);    // no loss
  ledger.lose(3, "c");  // [4, 12) by three, the rest of [0, 16) by two
  EXPECT_EQ(ledger.poisoned(3), (Range{4, 12}));
  EXPECT_EQ(ledger.poisoned(2), (Range{0, 16}));
  EXPECT_EQ(ledger.available(), 100u);
  EXPECT_EQ(ledger.grant(4, 100), (std::vector<Range>{{0, 100}}));
  ledger.done(4, {0, 100});
  EXPECT_TRUE(ledger.finished());
}

TEST(ClusterExchange, FractionSelectsRotatingChunks) {
  // S = 1: all chunks every time.
  auto all = exchange_chunks(7, 1.0, 8);
  EXPECT_EQ(all.size(), 8u);
  // S = 1/8 of 8 chunks: one chunk per exchange, each chunk once in 8 exchanges.
  std::vector<int> seen(8, 0);
  for (uint32_t e = 0; e < 8; ++e) {
    auto c = exchange_chunks(e, 0.125, 8);
    ASSERT_EQ(c.size(), 1u);
    ++seen[c[0]];
  }
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), 8);
  // S = 0.3 of 10 chunks: 3 per exchange, rotating.
  EXPECT_EQ(exchange_chunks(0, 0.3, 10), (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_EQ(exchange_chunks(4, 0.3, 10), (std::vector<uint32_t>{2, 3, 4}));
  EXPECT_THROW(exchange_chunks(0, 0.0, 10), Error);
  EXPECT_THROW(exchange_chunks(0, 1.5, 10), Error);
}

TEST(ClusterAggregate, CountWeightedEstimateStarAndRing) {
  auto starts = chunk_starts(5, 2);  // chunks of 2 and 3 patches
  ASSERT_EQ(starts, (std::vector<uint32_t>{0, 2, 5}));
  Aggregate agg(starts, 3);
  // Node p reports chunk 0 with every value (p + 1) * count: its mean is p + 1.
  const uint64_t counts[3] = {10, 30, 60};
  for (uint32_t p = 0; p < 3; ++p) agg.set(p, 0, std::vector<double>(6, (p + 1.0) * counts[p]), counts[p]);
  // Count-weighted: (10*1 + 30*2 + 60*3) / 100 = 2.5.
  for (double v : agg.estimate(0)) EXPECT_DOUBLE_EQ(v, 2.5);
  EXPECT_EQ(agg.count(0), 100u);
  for (double v : agg.estimate(1)) EXPECT_EQ(v, 0.0);  // nobody reported chunk 1
  // Star: node 1 receives nodes 0 and 2; ring: node 1 receives node 2, node 2 receives node 0.
  auto star = agg.others(1, 0, Topology::star);
  EXPECT_EQ(star.count, 70u);
  EXPECT_DOUBLE_EQ(star.sum[0], 10.0 + 180.0);
  auto ring = agg.others(1, 0, Topology::ring);
  EXPECT_EQ(ring.count, 60u);
  EXPECT_EQ(agg.others(2, 0, Topology::ring).count, 10u);
  // A late joiner starts empty and does not change the estimate until it reports.
  agg.add_node();
  for (double v : agg.estimate(0)) EXPECT_DOUBLE_EQ(v, 2.5);
}

// The combined error (Aggregate::combined_error): node 0 reported e = 0.1 after 100 bundles,
// node 1 e = 0.05 after 300. Chunk 0 holds both at those counts:
//     V = (100 * 100 * 0.01 + 300 * 300 * 0.0025) / 400^2 = 325 / 160000 -> 0.04507,
// chunk 1 holds node 1's older state of 100 bundles (its error then 0.05 sqrt(3)):
//     V = (100 * 100 * 0.01 + 100 * 300 * 0.0025) / 200^2 = 175 / 40000 -> 0.06614;
// with chunk weights 1 and 3 the run's estimate is sqrt((V0 + 3 V1) / 4). A node holding data
// without an estimate makes it unknown (-1).
TEST(ClusterAggregate, CombinedErrorWeighsTheCountsHeld) {
  Aggregate agg(chunk_starts(4, 2), 2);
  agg.set(0, 0, std::vector<double>(6, 1.0), 100);
  agg.set(0, 1, std::vector<double>(6, 1.0), 100);
  agg.set(1, 0, std::vector<double>(6, 1.0), 300);
  agg.set(1, 1, std::vector<double>(6, 1.0), 100);
  std::vector<double> weight = {0.5, 0.5, 1.5, 1.5};
  double v0 = 325.0 / 160000.0, v1 = 175.0 / 40000.0;
  EXPECT_NEAR(agg.combined_error({0.1, 0.05}, {100, 300}, weight), std::sqrt((v0 + 3 * v1) / 4), 1e-12);
  EXPECT_NEAR(agg.combined_error({0.1, 0.05}, {100, 300}, {1, 1, 0, 0}), std::sqrt(v0), 1e-12);
  EXPECT_EQ(agg.combined_error({0.1, -1.0}, {100, 300}, weight), -1.0);
  EXPECT_THROW(agg.combined_error({0.1}, {100}, weight), InvariantError);  // the policy gives one per node
}

// States are held as single-precision means (12 bytes per patch and node): every sum comes back
// within one float rounding of the mean, |mean| 2^-24, times the count; so does the estimate,
// a count-weighted mean of such means. A state read back and set again (a checkpoint's round
// trip) is held bit for bit: float -> double x count is exact below 2^29 bundles, and / count
// gives the same float back. Values span 1e-30 to 1e30 and both signs.
TEST(ClusterAggregate, StatesAreHeldToSinglePrecisionAndRoundTripExactly) {
  const uint32_t n = 500;
  Aggregate agg(chunk_starts(n, 1), 3);
  const uint64_t counts[3] = {7, 1000, (uint64_t{1} << 29) - 3};
  std::vector<std::vector<double>> sent(3);
  uint64_t state = 12345;
  auto next = [&state] {  // a fixed LCG: values of every magnitude and sign
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) / 9007199254740992.0;
  };
  for (uint32_t p = 0; p < 3; ++p) {
    sent[p].resize(3 * n);
    for (double& v : sent[p]) v = (next() < 0.1 ? -1.0 : 1.0) * std::pow(10.0, 60.0 * next() - 30.0) * static_cast<double>(counts[p]);
    agg.set(p, 0, sent[p], counts[p]);
  }
  std::vector<double> exact(3 * n, 0.0), bound(3 * n, 0.0);
  for (uint32_t p = 0; p < 3; ++p) {
    auto back = agg.state(p, 0);
    ASSERT_EQ(back.count, counts[p]);
    for (std::size_t i = 0; i < back.sum.size(); ++i) {
      const double tolerance = std::ldexp(std::fabs(sent[p][i]), -24) * (1.0 + 1e-9);
      ASSERT_LE(std::fabs(back.sum[i] - sent[p][i]), tolerance) << p << " " << i;
      exact[i] += sent[p][i];
      bound[i] += tolerance;
    }
    agg.set(p, 0, back.sum, back.count);
    auto again = agg.state(p, 0);
    ASSERT_EQ(0, std::memcmp(again.sum.data(), back.sum.data(), back.sum.size() * sizeof(double))) << p;
  }
  const double total = static_cast<double>(counts[0] + counts[1] + counts[2]);
  auto estimate = agg.estimate(0);
  for (std::size_t i = 0; i < estimate.size(); ++i)
    ASSERT_LE(std::fabs(estimate[i] - exact[i] / total), bound[i] / total + std::ldexp(std::fabs(exact[i] / total), -50)) << i;
}

TEST(ClusterAggregate, RefusesImpossibleStates) {
  Aggregate agg(chunk_starts(4, 2), 2);
  agg.set(0, 1, std::vector<double>(6, 1.0), 5);
  EXPECT_THROW(agg.set(0, 1, std::vector<double>(6, 1.0), 4), Error);  // count backwards
  EXPECT_THROW(agg.set(0, 1, std::vector<double>(5, 1.0), 6), Error);  // wrong size
  EXPECT_THROW(agg.set(0, 2, std::vector<double>(6, 1.0), 6), Error);  // no such chunk
  auto nan = std::vector<double>(6, 1.0);
  nan[3] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(agg.set(1, 0, nan, 1), Error);
  EXPECT_THROW(agg.set(1, 0, std::vector<double>(6, 1e39), 1), Error);   // beyond any float estimate
  EXPECT_THROW(agg.set(1, 0, std::vector<double>(6, 1.0), 0), Error);    // values from no bundle
  agg.set(1, 1, std::vector<double>(6, -1.0), 2);  // signed sums are legal (control variate)
  EXPECT_EQ(agg.state(1, 1).count, 2u);
  EXPECT_EQ(agg.state(0, 1).count, 5u);  // unchanged by the refusals
  EXPECT_EQ(agg.count(0), 0u);
  EXPECT_THROW(chunk_starts(3, 4), Error);
  EXPECT_THROW(parse_topology("mesh"), Error);
  EXPECT_THROW(parse_mode("eventually"), Error);
  EXPECT_EQ(parse_exchange_every("end"), 0u);
  EXPECT_EQ(parse_exchange_every("16"), 16u);
  for (const char* bad : {"0", "-3", "often", "16x", "", "99999999999"}) EXPECT_THROW(parse_exchange_every(bad), Error) << bad;
}

// The coordinator's bookkeeping: a node index only the coordinator itself hands out is an
// invariant; a chunk a node's message names is input.
TEST(Invariants, TheAggregateTellsItsOwnIndicesFromANodesMessage) {
  Aggregate aggregate({0, 2, 4}, 2);
  EXPECT_THROW(aggregate.clear(5), InvariantError);
  EXPECT_THROW(aggregate.check(0, 7, std::vector<double>(6, 0.0), 1), Error);
}

}  // namespace
}  // namespace sirad::cluster
