// sirad tests: the coordinator's decisions (cluster/policy.h) as plain state.
#include <cmath>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "cluster/policy.h"
#include "util/error.h"

namespace sirad::cluster {
namespace {

Policy make(PolicyConfig c, uint32_t nodes) {
  Policy p(c, chunk_starts(64, 4), std::vector<double>(64, 1.0));
  for (uint32_t n = 0; n < nodes; ++n) p.join();
  return p;
}

uint64_t size_of(const GrantOrder& g) {
  uint64_t s = 0;
  for (const Range& r : g.ranges) s += r.size();
  return s;
}

// Balanced grants: each node's grant is I times the fastest node's bundle time over its own,
// rounded up to a power of two: 1.5x slower is noise (I), 4x slower gets I / 4; never above I.
TEST(Policy, BalancedGrantsFollowTheNodesSpeeds) {
  PolicyConfig c{.bundles = 100000, .exchange_every = 16, .mode = Mode::sync, .min_nodes = 4, .grant_unit = 2};
  Policy p = make(c, 4);
  const double t[] = {1.0, 1.5, 4.0, 3.5};
  for (uint32_t n = 0; n < 4; ++n) {
    p.ready(n);
    p.set_bundle_time(n, t[n]);
  }
  Orders o = p.next_work();
  ASSERT_EQ(o.grants.size(), 4u);
  EXPECT_EQ(size_of(o.grants[0]), 16u);  // the fastest
  EXPECT_EQ(size_of(o.grants[1]), 16u);  // 1.5x: below 2x, exactly I
  EXPECT_EQ(size_of(o.grants[2]), 4u);   // 4x: I / 4
  EXPECT_EQ(size_of(o.grants[3]), 8u);   // 3.5x: I / 2
  // Off: every grant I.
  c.balance = false;
  Policy q = make(c, 4);
  for (uint32_t n = 0; n < 4; ++n) {
    q.ready(n);
    q.set_bundle_time(n, t[n]);
  }
  for (const GrantOrder& g : q.next_work().grants) EXPECT_EQ(size_of(g), 16u);
}

// Without exchanges a grant is an eighth of a node's share of the bundles, unless the run ends
// at a target error or a time limit: then at most kTargetReportBundles, so that a run of a
// large budget hears of its end within a grant (a 6 s limit on 1e8 bundles at 70 ms each ran
// for hours with 1.25e7-bundle grants).
TEST(Policy, RunsThatEndEarlyGetShortGrantsWithoutExchanges) {
  PolicyConfig c{.bundles = 100000000, .exchange_every = 0, .mode = Mode::async, .min_nodes = 1};
  EXPECT_EQ(make(c, 1).grant_size(), 100000000u / 8);
  c.time_limit_s = 6;
  EXPECT_EQ(make(c, 1).grant_size(), Policy::kTargetReportBundles);
  c.time_limit_s = 0;
  c.target_error = 0.01;
  EXPECT_EQ(make(c, 1).grant_size(), Policy::kTargetReportBundles);
}

// A grant's time bound: 8 times its bundles at the node's bundle time (measured, else its
// READY's claim, else 1 s), that time at most 16 times the fastest ready node's and at most
// 10 s: a node claiming to be slow cannot buy itself a deadline far beyond the others'.
TEST(Policy, GrantTimeBoundFollowsMeasuredSpeedsWithinBounds) {
  PolicyConfig c{.bundles = 1000, .exchange_every = 16, .mode = Mode::async, .min_nodes = 3};
  Policy p = make(c, 3);
  for (uint32_t n = 0; n < 3; ++n) p.ready(n);
  EXPECT_DOUBLE_EQ(p.grant_time_bound(0, 16, 0.0), 8 * 16 * 1.0);     // nothing known: 1 s
  EXPECT_DOUBLE_EQ(p.grant_time_bound(0, 16, 0.002), 8 * 16 * 0.002); // its claim
  EXPECT_DOUBLE_EQ(p.grant_time_bound(0, 16, 1e9), 8 * 16 * 10.0);    // at most 10 s a bundle
  p.set_bundle_time(0, 0.001);
  p.set_bundle_time(1, 0.004);
  EXPECT_DOUBLE_EQ(p.grant_time_bound(1, 16, 0.5), 8 * 16 * 0.004);   // measured beats claimed
  EXPECT_DOUBLE_EQ(p.grant_time_bound(2, 16, 1e9), 8 * 16 * 0.016);   // 16 x the fastest
  p.dead(0);                                                           // the fastest gone: 16 x 0.004
  EXPECT_DOUBLE_EQ(p.grant_time_bound(2, 16, 1e9), 8 * 16 * 0.064);
}

// Quarantine: a report with a value no node can send (NaN), a count beyond its bundles or done
// ranges it was not granted drops the node's data and returns its bundles, done or not; its
// earlier accepted report goes too. A late report from it is refused without changing anything.
TEST(Policy, QuarantineDropsTheDataAndReturnsTheBundles) {
  struct Case {
    const char* name;
    double value;
    uint64_t count_factor;
    bool foreign_range;
  };
  for (const Case& k : {Case{"nan", std::nan(""), 1, false}, Case{"count", 1.0, 2, false}, Case{"range", 1.0, 1, true}}) {
    SCOPED_TRACE(k.name);
    PolicyConfig c{.bundles = 64, .exchange_every = 8, .mode = Mode::async, .min_nodes = 2, .balance = false};
    Policy p = make(c, 2);
    p.ready(0);
    p.ready(1);
    Orders o = p.next_work();
    ASSERT_EQ(o.grants.size(), 4u);  // two each, 8 bundles: node 0 holds 0 and 1, node 1 holds 2 and 3
    auto chunk = [](double v, uint64_t count) { return ChunkState{0, std::vector<double>(48, v * static_cast<double>(count)), count}; };
    p.take_result(1, o.grants[2].id, o.grants[2].ranges, {chunk(5.0, 8)}, 0);  // node 1's first: accepted
    EXPECT_EQ(p.aggregate().count(0), 8u);
    std::vector<Range> done = k.foreign_range ? o.grants[0].ranges : o.grants[3].ranges;
    EXPECT_THROW(p.take_result(1, o.grants[3].id, done, {chunk(k.value, 16 * k.count_factor)}, 0), Error);
    EXPECT_TRUE(p.node(1).quarantined);
    EXPECT_STREQ(p.node(1).state(), "quarantined");
    EXPECT_EQ(p.aggregate().count(0), 0u) << "its accepted state is dropped too";
    EXPECT_EQ(p.ledger().done_count(), 0u);
    EXPECT_EQ(p.ledger().available(), 64u - 16u) << "only node 0's grants are out";
    EXPECT_THROW(p.take_result(1, o.grants[3].id, o.grants[3].ranges, {}, 0), Error);
    EXPECT_EQ(p.ledger().done_count(), 0u);
  }
}

// Sync: no grant while any node holds one; the last report opens the next round, and a node
// declared dead does not hold it up. Each index is granted once.
TEST(Policy, SyncGrantsARoundOnlyWhenTheLastIsIn) {
  PolicyConfig c{.bundles = 64, .exchange_every = 8, .mode = Mode::sync, .min_nodes = 2};
  Policy p = make(c, 3);
  p.ready(0);
  EXPECT_TRUE(p.next_work().grants.empty());  // min_nodes
  p.ready(1);
  p.ready(2);
  Orders first = p.next_work();
  ASSERT_EQ(first.grants.size(), 3u);
  p.take_result(0, first.grants[0].id, first.grants[0].ranges, {}, 0);
  EXPECT_TRUE(p.next_work().grants.empty());
  EXPECT_EQ(p.dead(2), 8u);  // its grant goes back
  EXPECT_TRUE(p.next_work().grants.empty());  // node 1 still holds one
  p.take_result(1, first.grants[1].id, first.grants[1].ranges, {}, 0);
  Orders second = p.next_work();
  ASSERT_EQ(second.grants.size(), 2u);
  EXPECT_EQ(second.grants[0].ranges.front().first, 16u);  // node 2's returned range first
  EXPECT_THROW(p.take_result(0, first.grants[0].id, first.grants[0].ranges, {}, 0), Error);  // answered already
}

// Bundles that crash whoever runs them: the lowest free indices go out first, so the first
// grant goes to node after node, each dying with it. At the third loss by a distinct node the
// run closes (no more grants, ended_by naming the bundles) and, no live node holding a grant,
// it is done. Deaths that count no loss (dead(): an emulated disconnect, a HELLO again), or
// losses by one peer that keeps coming back, leave the run granting.
TEST(Policy, BundlesLostWithThreeNodesCloseTheRun) {
  for (const std::string how : {"lost", "dead", "one peer"}) {
    const bool planned = how != "lost";
    PolicyConfig c{.bundles = 64, .exchange_every = 8, .mode = Mode::async, .min_nodes = 1};
    Policy p = make(c, 0);
    uint64_t held = 0;  // what each node held when it died: two grants of 8
    for (uint32_t n = 0; n < 3; ++n) {
      EXPECT_EQ(p.join(), n);
      p.ready(n);
      Orders o = p.next_work();
      ASSERT_FALSE(o.grants.empty()) << how << " " << n;
      EXPECT_EQ(o.grants.front().ranges.front().first, 0u);  // the lost bundles first
      held = p.grant_size() * o.grants.size();
      EXPECT_EQ(how == "dead" ? p.dead(n) : p.lost(n, how == "lost" ? fmt::format("10.0.0.{}", n) : "10.0.0.9"), held);
    }
    EXPECT_EQ(p.ended_by().empty(), planned);
    p.join();
    p.ready(3);
    if (planned) {
      EXPECT_FALSE(p.next_work().grants.empty());
      continue;
    }
    EXPECT_EQ(held, 16u);
    EXPECT_NE(p.ended_by().find(fmt::format("bundles 0..{} were lost with 3 nodes", held - 1)), std::string::npos) << p.ended_by();
    Orders after = p.next_work();
    EXPECT_TRUE(after.grants.empty());
    EXPECT_EQ(after.stops, (std::vector<uint32_t>{3}));
    EXPECT_TRUE(p.ending());
  }
}

// --exchange-every auto: chosen once, when the first grants go out, from the ready nodes.
TEST(Policy, AutoExchangeIsChosenOnceAtTheStart) {
  int calls = 0;
  PolicyConfig c{.bundles = 640, .exchange_every = kExchangeAuto, .mode = Mode::async, .min_nodes = 2};
  c.choose = [&](const std::vector<uint32_t>& ready) {
    ++calls;
    EXPECT_EQ(ready.size(), 2u);
    return ExchangeSetting{5, 0.5, "test"};
  };
  Policy p = make(c, 2);
  p.ready(0);
  p.next_work();
  EXPECT_EQ(calls, 0);
  p.ready(1);
  Orders o = p.next_work();
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(p.exchange_every(), 5u);
  EXPECT_EQ(p.fraction(), 0.5);
  EXPECT_EQ(p.exchange_why(), "test");
  ASSERT_FALSE(o.grants.empty());
  EXPECT_EQ(size_of(o.grants[0]), 5u);
  EXPECT_EQ(o.grants[0].report_chunks.size(), 2u);  // S = 1/2 of 4 chunks
  p.next_work();
  EXPECT_EQ(calls, 1);
}

// The chain rule's auto: S = 1 and I = max over nodes of ceil(e_p / t_p) in async, of
// ceil(10 e_p / t_p) in sync, capped at bundles / (8 P). Node 1's transfer (0.2 s) over its
// bundle (0.01 s): 20 and 200.
TEST(Policy, ChainRuleAutoLetsEveryLinkKeepUp) {
  ExchangeSetting s = auto_exchange(UpdateRule::chain, {}, {{0.01, 0.01}, {0.01, 0.2}}, Mode::async, 100000, 16);
  EXPECT_EQ(s.exchange_every, 20u);
  EXPECT_EQ(s.fraction, 1.0);
  EXPECT_EQ(auto_exchange(UpdateRule::chain, {}, {{0.01, 0.01}, {0.01, 0.2}}, Mode::sync, 100000, 16).exchange_every, 200u);
  ExchangeSetting capped = auto_exchange(UpdateRule::chain, {}, {{0.01, 0.01}, {0.01, 0.2}}, Mode::sync, 320, 16);
  EXPECT_EQ(capped.exchange_every, 20u);  // 320 / (8 x 2)
}

// The coordinator's link carries every node's report: with c = 0.05 s per state and two nodes
// of 100 bundles/s each, I >= c x 200 = 10 in async (100 in sync), over the nodes' own 1
// (their links: 0.005 s / 0.01 s). Under the average rule it is charged P S c per exchange, so
// a slow coordinator link makes the model exchange less often.
TEST(Policy, AutoChargesTheCoordinatorsLinkForEveryNode) {
  const std::vector<NodeCost> nodes{{0.01, 0.005}, {0.01, 0.005}};
  EXPECT_EQ(auto_exchange(UpdateRule::chain, {}, nodes, Mode::async, 100000, 16).exchange_every, 1u);
  EXPECT_EQ(auto_exchange(UpdateRule::chain, {}, nodes, Mode::async, 100000, 16, 0, 0.05).exchange_every, 10u);
  EXPECT_EQ(auto_exchange(UpdateRule::chain, {}, nodes, Mode::sync, 100000, 16, 0, 0.05).exchange_every, 100u);
  const model::Scene scene{0.5, 1.0};
  ExchangeSetting free_hub = auto_exchange(UpdateRule::average, scene, nodes, Mode::sync, 2000, 16);
  ExchangeSetting slow_hub = auto_exchange(UpdateRule::average, scene, nodes, Mode::sync, 2000, 16, 0, 0.05);
  EXPECT_GT(slow_hub.exchange_every / slow_hub.fraction, free_hub.exchange_every / free_hub.fraction)
      << free_hub.why << " / " << slow_hub.why;
  EXPECT_NE(slow_hub.why.find("T_e 0.05 s"), std::string::npos) << slow_hub.why;
}

// Node entries are capped: past kMaxNodeEntries a new node takes the index of the oldest
// departed entry that holds nothing (here: entries that joined and died, and one quarantined),
// never one whose data are in the estimate or whose bundles are in the ledger; when every entry
// holds something, joining is refused.
TEST(Policy, NodeEntriesAreCappedByReusingEmptyDepartedOnes) {
  PolicyConfig c{.bundles = 1u << 20, .exchange_every = 4, .mode = Mode::async, .min_nodes = 1, .balance = false};
  Policy p(c, chunk_starts(64, 4), std::vector<double>(64, 1.0));
  // Node 0 works: reports a state and done bundles, then dies (its record must stay).
  p.join();
  p.ready(0);
  GrantOrder g = p.next_work().grants.front();
  p.take_result(0, g.id, g.ranges, {ChunkState{0, std::vector<double>(48, 4.0), 4}}, 0.0);
  p.dead(0);
  for (uint32_t n = 1; n < Policy::kMaxNodeEntries; ++n) {
    ASSERT_EQ(p.join(), n);
    p.dead(n);
  }
  EXPECT_EQ(p.nodes(), Policy::kMaxNodeEntries);
  EXPECT_EQ(p.join(), 1u);  // the oldest empty one: node 0 holds data
  EXPECT_EQ(p.nodes(), Policy::kMaxNodeEntries);
  EXPECT_FALSE(p.node(1).dead);
  EXPECT_EQ(p.ledger().done_by(0).size(), 1u);
  EXPECT_EQ(p.aggregate().state(0, 0).count, 4u);
  EXPECT_EQ(p.join(), 2u);
  // Every entry holding something: refused.
  Policy q(c, chunk_starts(64, 4), std::vector<double>(64, 1.0));
  for (uint32_t n = 0; n < Policy::kMaxNodeEntries; ++n) {
    q.join();
    q.ready(n);
  }
  for (const GrantOrder& o : q.next_work().grants)
    if (q.node(o.node).grants.front() == o.id) q.take_result(o.node, o.id, o.ranges, {}, 0.0);
  for (uint32_t n = 0; n < Policy::kMaxNodeEntries; ++n) q.dead(n);
  EXPECT_THROW(q.join(), Error);
  q.quarantine(7, "test");  // its bundles go back: it holds nothing now
  EXPECT_EQ(q.join(), 7u);
}

}  // namespace
}  // namespace sirad::cluster
