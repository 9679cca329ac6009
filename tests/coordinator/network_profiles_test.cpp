// sirad tests: the cluster under an emulation profile (cluster/profile.h) over real
// ZeroMQ sockets: a slowed node in async mode, a node that drops off (liveness), one that comes
// back, and links whose latency and bandwidth the messages must honour.
#include <chrono>
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "solver/metrics.h"
#include "tests/cluster_util.h"

namespace sirad::cluster {
namespace {

using test::furnace;
using test::node_named;
using test::Outcome;
using test::run_cluster;

uint64_t total_bundles(const RunResult& r) {
  uint64_t total = 0;
  for (const auto& n : r.nodes) total += n.bundles;
  return total;
}

// Async mode, one node of three at a quarter of the speed. Every node works from the first
// grant to the end, so node i does b_i = r_i T_i bundles at its own rate r_i = b_i / T_i over
// its working span T_i = busy_i + idle_i; the spans differ only by the last grant (the slow
// node may finish its last grant of g = 8 bundles after the others stopped), so the slow
// node's share is K r_s / sum_i r_i within one grant. The fast nodes never wait on it: their idle time (from
// a REPORT to the next GRANT, answered at once in async mode) stays near zero. The furnace
// stays unbiased: 4 standard deviations of a 2000-bundle chain average, 0.04 sqrt(1024/2000).
// Idle bound: 2 % of busy time for the REPORT-to-GRANT round trips, plus the run's tail, when the
// budget is given out and the fast nodes wait for the slow node's outstanding work: with the
// async grant queue of depth 2 that is up to 2 grants, 16 slow bundles (one grant, as first
// written, was too little: a loaded parallel ctest measured 16.6 slow-bundle times of idle).
TEST(Emulation, AsyncSlowNodeTakesProportionallyFewerAndNobodyWaits) {
  RunConfig c = furnace(2000);
  c.mesh_options.target_patches = 1200;  // bundles of about a millisecond, grants of 8
  c.exchange_every = 8;
  c.mode = Mode::async;
  c.profile = emulation::parse_profile("nodes:\n  - name: n2\n    speed: 0.25\n", "test");
  Outcome o = run_cluster(c, 3, "inproc://emulation-slow");
  ASSERT_EQ(o.result.nodes.size(), 3u);
  EXPECT_EQ(total_bundles(o.result), 2000u);
  double rates = 0;
  for (const auto& n : o.result.nodes) {
    std::printf("%s: %llu bundles, busy %.3f s, idle %.4f s, %.1f bundles/s of its time\n", n.name.c_str(),
                static_cast<unsigned long long>(n.bundles), n.busy_s, n.idle_s, n.bundles / (n.busy_s + n.idle_s));
    rates += n.bundles / (n.busy_s + n.idle_s);
  }
  const NodeReport& slow = node_named(o.result, "n2");
  double share = 2000.0 * (slow.bundles / (slow.busy_s + slow.idle_s)) / rates;
  std::printf("slow node: %llu bundles, proportional share %.1f\n", static_cast<unsigned long long>(slow.bundles), share);
  EXPECT_NEAR(static_cast<double>(slow.bundles), share, 8.0 + 1.0);
  for (const char* fast : {"n0", "n1"}) {
    const NodeReport& f = node_named(o.result, fast);
    EXPECT_LT(slow.bundles / slow.busy_s, 0.4 * f.bundles / f.busy_s) << "the slowdown acted";
    EXPECT_LT(f.idle_s, 0.02 * f.busy_s + 2 * 8 / (slow.bundles / (slow.busy_s + slow.idle_s))) << fast << " waited";
  }
  EXPECT_NEAR(area_mean(o.mesh, o.result.radiosity), 2.0, 0.04 * std::sqrt(1024.0 / 2000.0));
}

// A node that drops off for good (the profile disconnects it 1 s after it is ready): the
// coordinator hears nothing for 3 heartbeats of 50 ms, declares it dead, returns its grant to
// the budget, and the run still ends with every bundle index done exactly once (the ledger
// refuses any other count, and strict mode turns that into a failed run) and unbiased. The node
// must have done bundles before it drops off: its disconnect clock starts at its READY, so its
// first grant must not wait for the other nodes (min_nodes 1: with all 3, a cold PoCL cache
// held the grants past the disconnect), and 1 s lets that grant run and report on a loaded
// machine. The run must outlast 1.15 s: 64000 furnace bundles take about 3 s on 2 cores.
TEST(Emulation, DeadNodeGrantReturnsAndTheRunCompletes) {
  RunConfig c = furnace(64000);
  c.exchange_every = 8;
  c.heartbeat_ms = 50;
  c.liveness = 3;
  c.profile = emulation::parse_profile("nodes:\n  - name: n1\n    disconnect_at_s: 1\n", "test");
  Outcome o = run_cluster(c, 3, "inproc://emulation-dead", 1);
  ASSERT_EQ(o.result.nodes.size(), 3u);
  const NodeReport& gone = node_named(o.result, "n1");
  EXPECT_TRUE(gone.dead);
  EXPECT_GT(gone.bundles, 0u);
  EXPECT_FALSE(node_named(o.result, "n0").dead);
  EXPECT_EQ(total_bundles(o.result), 64000u);
  EXPECT_NEAR(area_mean(o.mesh, o.result.radiosity), 2.0, 0.04 * std::sqrt(1024.0 / 64000.0));
}

// A node that drops off and comes back 0.2 s later rejoins as a new peer with a fresh state;
// its former entry stays (dead) with its last accepted state, and the run completes. n1's
// disconnect clock starts at its READY, so its first grant must not wait for the other node
// (min_nodes 1: with both, a cold PoCL cache in a fresh clone held the grants past a 0.2 s
// disconnect and n1's first entry ran nothing), and the 1 s before it drops off lets that grant
// run and report on a loaded machine. K is large enough for the run to outlast n1's return
// (about 3.5 s on 2 cores, 2 s after it) so that the new peer sets up and takes grants.
TEST(Emulation, NodeThatReconnectsRejoinsAsANewPeer) {
  RunConfig c = furnace(64000);
  c.exchange_every = 8;
  c.heartbeat_ms = 100;
  c.profile = emulation::parse_profile(
      "nodes:\n  - name: n1\n    disconnect_at_s: 1\n    reconnect_after_s: 0.2\n", "test");
  Outcome o = run_cluster(c, 2, "inproc://emulation-rejoin", 1);
  ASSERT_EQ(o.result.nodes.size(), 3u);
  int dead = 0, back = 0;
  for (const auto& n : o.result.nodes)
    if (n.name == "n1") {
      (n.dead ? dead : back) += 1;
      EXPECT_GT(n.bundles, 0u);
    }
  EXPECT_EQ(dead, 1);
  EXPECT_EQ(back, 1);
  EXPECT_EQ(total_bundles(o.result), 64000u);
  EXPECT_NEAR(area_mean(o.mesh, o.result.radiosity), 2.0, 0.04 * std::sqrt(1024.0 / 64000.0));
}

// A harsh link: 10 % packet loss on every link (each lost packet costs a retransmission timeout
// of >= 200 ms, as over TCP; no data is lost) and node n1 dropping off for 2 s 1 s after it is
// ready. The run still finishes correctly: exactly K bundles, every index once in the ledger
// (across n1's dead entry and its rejoined one, both of which ran bundles), and the furnace
// unbiased within 4 sd of a K-bundle chain average (0.0097 sqrt(1024 / K) 4). n1's clock starts
// at its READY, so the first grant must not wait for the other nodes (min_nodes 1: with all 3,
// a cold PoCL cache in a fresh clone held the grants past n1's disconnect), and the 1 s gives
// that grant time to arrive and run through lost packets on a loaded machine; K is large
// enough for the run to outlast n1's return (about 6 s on 2 cores: the loss slows it 4x).
TEST(Emulation, TenPercentLossAndATwoSecondDisconnectStillFinishCorrectly) {
  const uint64_t K = 8000;
  RunConfig c = furnace(K);
  c.exchange_every = 16;  // the default heartbeat (1 s): a lost packet's 200 ms retransmission is no silence
  c.profile = emulation::parse_profile(
      "defaults:\n  loss: 0.1\n  latency_ms: 2\nnodes:\n  - name: n1\n    disconnect_at_s: 1\n"
      "    reconnect_after_s: 2\n",
      "test");
  Outcome o = run_cluster(c, 3, "inproc://emulation-harsh", 1);
  EXPECT_EQ(o.result.bundles, K);
  EXPECT_EQ(total_bundles(o.result), K);
  int dead = 0, back = 0;
  for (const auto& n : o.result.nodes)
    if (n.name == "n1") {
      (n.dead ? dead : back) += 1;
      EXPECT_GT(n.bundles, 0u) << (n.dead ? "before" : "after") << " the disconnect";
    }
  EXPECT_EQ(dead, 1);
  EXPECT_EQ(back, 1) << "n1 came back after 2 s and rejoined";
  std::vector<int> seen(K, 0);
  for (const LedgerEntry& e : o.result.ledger)
    for (uint64_t k = e.range.first; k < e.range.last; ++k) ++seen[k];
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<long>(K)) << "every index exactly once";
  EXPECT_NEAR(area_mean(o.mesh, o.result.radiosity), 2.0, 0.0097 * std::sqrt(1024.0 / K) * 4);
}

// Latency and bandwidth are honoured: in sync mode every exchange round is a REPORT up and an
// UPDATE and GRANT down, so a node waits at least 2 latency + report bits / up + update bits /
// down per round; with 8 rounds (K = 256, I = 16, 2 nodes) its idle time is at least 7 of them
// (the first grant's wait is not counted). A lower bound only: the machine adds to it.
TEST(Emulation, LinksDelayMessagesByLatencyAndBandwidth) {
  RunConfig c = furnace(256);
  c.exchange_every = 16;
  c.mode = Mode::sync;
  c.chunks = 4;
  c.balance = false;  // grants of exactly I bundles: a loaded machine can make one node look 2x slower
  c.profile = emulation::parse_profile("defaults:\n  latency_ms: 15\n  up_mbit: 2\n  down_mbit: 4\n", "test");
  Outcome o = run_cluster(c, 2, "inproc://emulation-links");
  double state_bits = 24.0 * o.mesh.size() * 8;  // S = 1: every patch's 3 doubles each way
  double round = 2 * 0.015 + state_bits / 2e6 + state_bits / 4e6;
  for (const auto& n : o.result.nodes) {
    std::printf("%s: idle %.3f s over 7 rounds of at least %.3f s\n", n.name.c_str(), n.idle_s, round);
    EXPECT_EQ(n.exchanges, 8u);
    EXPECT_GE(n.idle_s, 7 * round);
  }
  EXPECT_NEAR(area_mean(o.mesh, o.result.radiosity), 2.0, 0.04 * std::sqrt(1024.0 / 256.0));
}

}  // namespace
}  // namespace sirad::cluster

namespace sirad::cluster {
namespace {

double furnace_rms(const test::Outcome& o) {
  double s = 0;
  for (const auto& b : o.result.radiosity) s += (b.x / 2.0 - 1.0) * (b.x / 2.0 - 1.0);
  return std::sqrt(s / static_cast<double>(o.result.radiosity.size()));
}

// A target error ends the run early, once the spread of three independent chains says the
// relative error per patch is at or below it. The estimate is rough: with 3 chains it has 2
// degrees of freedom per patch, and the furnace's patch errors share each chain's common mode,
// so few effective ones in all; and the run stops at the estimate's first dip below the target.
// Measured true errors at the stop: 0.0148 .. 0.0317 for a target of 0.03 (8 runs). We check the true
// error is under twice the target (the stop is not premature) and over a quarter of it (the
// estimate is not grossly pessimistic); issue 4 calibrates the estimate properly.
TEST(RunEnds, AtTheTargetError) {
  RunConfig c = furnace(20000);  // about 10 s if the target never ends it
  c.exchange_every = 8;
  c.target_error = 0.03;
  c.control_variate = false;  // with it the furnace is nearly exact at once (solver_test.cpp)
  Outcome o = run_cluster(c, 3, "inproc://ends-target");
  double rms = furnace_rms(o);
  std::printf("target 0.03: ended after %llu bundles (%s), true RMS error %.4f\n",
              static_cast<unsigned long long>(o.result.bundles), o.result.ended_by.c_str(), rms);
  EXPECT_EQ(o.result.ended_by.rfind("target error", 0), 0u);
  EXPECT_LT(o.result.bundles, 20000u);
  EXPECT_EQ(total_bundles(o.result), o.result.bundles);
  EXPECT_GT(rms, 0.03 / 4);
  EXPECT_LT(rms, 0.03 * 2);
}

// A time limit ends the run early too: no grants after it, the outstanding ones finish, every
// node's final state is in, and the bundles counted are exactly those done.
TEST(RunEnds, AtTheTimeLimit) {
  RunConfig c = furnace(1000000);
  c.exchange_every = 8;
  c.time_limit_s = 1.0;
  Outcome o = run_cluster(c, 2, "inproc://ends-time");
  EXPECT_EQ(o.result.ended_by, "time limit");
  EXPECT_GT(o.result.bundles, 0u);
  EXPECT_LT(o.result.bundles, 1000000u);
  EXPECT_EQ(total_bundles(o.result), o.result.bundles);
  EXPECT_NEAR(area_mean(o.mesh, o.result.radiosity), 2.0, 0.04 * std::sqrt(1024.0 / o.result.bundles));
}

}  // namespace
}  // namespace sirad::cluster
