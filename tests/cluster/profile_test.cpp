// sirad tests: network-emulation profiles (parsing, matching, errors with file:line) and the
// link model (bandwidth, latency, jitter, order, loss as TCP retransmissions).
#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "cluster/profile.h"
#include "util/error.h"

namespace sirad::emulation {
namespace {

std::string error_of(const std::string& text) {
  try {
    parse_profile(text, "p.yaml");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Profile, EntriesOverrideDefaultsAndMatchByNameOrIndex) {
  Profile p = parse_profile(
      "profile: t\n"
      "defaults:\n"
      "  latency_ms: 0.5\n"
      "  bandwidth_mbit: 1000\n"
      "nodes:\n"
      "  - name: slow\n"
      "    speed: 0.25\n"
      "    up_mbit: 10\n"
      "  - index: 1\n"
      "    loss: 0.01\n"
      "    disconnect_at_s: 3\n",
      "t.yaml");
  EXPECT_EQ(p.name, "t");
  LinkSpec slow = p.for_node(7, "slow");
  EXPECT_EQ(slow.speed, 0.25);
  EXPECT_EQ(slow.up_mbit, 10);
  EXPECT_EQ(slow.down_mbit, 1000);   // from the defaults
  EXPECT_EQ(slow.latency_ms, 0.5);
  LinkSpec one = p.for_node(1, "other");
  EXPECT_EQ(one.loss, 0.01);
  EXPECT_EQ(one.disconnect_at_s, 3);
  EXPECT_EQ(one.reconnect_after_s, -1);
  EXPECT_EQ(p.for_node(1, "slow"), slow);  // the first entry in file order wins
  EXPECT_EQ(p.for_node(2, "x"), p.defaults);
  // Speeds are relative to the fastest: the defaults (1) run at real speed, "slow" 4x slower.
  EXPECT_EQ(p.slowdown(p.defaults), 1.0);
  EXPECT_EQ(p.slowdown(slow), 4.0);
}

TEST(Profile, BadInputIsOneLineNamingFileLineAndKey) {
  EXPECT_EQ(error_of("defaults:\n  loss: 0.7\n"), "p.yaml:2: defaults.loss: 0.7 is not in [0, 0.5]");
  EXPECT_EQ(error_of("defaults:\n  speed: fast\n"), "p.yaml:2: defaults.speed: expected a number, got 'fast'");
  EXPECT_EQ(error_of("defaults:\n  speed: .nan\n"), "p.yaml:2: defaults.speed: .nan is not in [0.001, 1000]");
  EXPECT_NE(error_of("defaults:\n  latency: 3\n").find("p.yaml:2: defaults.latency: unknown key"), std::string::npos);
  EXPECT_EQ(error_of("nodes:\n  - speed: 2\n"), "p.yaml:2: nodes[0]: an entry needs a name or an index");
  EXPECT_EQ(error_of("nodes:\n  - index: 1.5\n"), "p.yaml:2: nodes[0].index: expected a whole number");
  EXPECT_EQ(error_of("nodes:\n  - index: -1\n"), "p.yaml:2: nodes[0].index: -1 is not in [0, 1048576]");
  EXPECT_EQ(error_of("nodes: 3\n"), "p.yaml:1: nodes: expected a list of entries");
  EXPECT_EQ(error_of("nodez: []\n"), "p.yaml:1: unknown key 'nodez' (known: profile, defaults, nodes, coordinator)");
  EXPECT_EQ(error_of("coordinator:\n  speed: 2\n"),
            "p.yaml:2: coordinator.speed: not a setting of the coordinator's link (known: latency_ms, jitter_ms, bandwidth_mbit, "
            "up_mbit, down_mbit, loss)");
  EXPECT_EQ(error_of("coordinator:\n  bandwidth_mbit: 0\n"), "p.yaml:2: coordinator.bandwidth_mbit: 0 is not in [0.001, 1000000]");
  EXPECT_EQ(error_of("coordinator: 5\n"), "p.yaml:1: coordinator: expected a map of settings");
  EXPECT_EQ(error_of("- 1\n- 2\n"), "p.yaml: a profile is a map with 'defaults' and 'nodes' (see deploy/profiles/)");
  EXPECT_EQ(error_of("defaults:\n  reconnect_after_s: 2\n"), "p.yaml:2: defaults: reconnect_after_s without disconnect_at_s");
  EXPECT_NE(error_of("defaults: [1, 2\n").find("p.yaml:"), std::string::npos);
  EXPECT_NE(error_of("defaults: {speed: 1\n").find("not valid YAML"), std::string::npos);
  // A list or map as a key (yaml-cpp: "bad conversion", no line) and deep nesting (yaml-cpp:
  // "bad file") each get their reason.
  EXPECT_EQ(error_of("nodes:\n  - ? [a, b]\n    : 3\n"), "p.yaml:2: a key is a plain name, not a list or a map");
  EXPECT_EQ(error_of("? {a: 1}\n: 3\n"), "p.yaml:1: a key is a plain name, not a list or a map");
  EXPECT_EQ(error_of("profile: [x]\n"), "p.yaml:1: profile: expected a name");
  EXPECT_EQ(error_of("nodes: " + std::string(100000, '[') + std::string(100000, ']') + "\n"),
            "p.yaml: lists or maps nested deeper than 64 levels");
  try {
    load_profile("/nonexistent/x.yaml");
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("/nonexistent/x.yaml: cannot read the profile", 0), 0u);
  }
}

// The coordinator's own link: up into it, down out of it; absent, none.
TEST(Profile, TheCoordinatorsLinkIsItsOwnEntry) {
  EXPECT_FALSE(parse_profile("defaults: {bandwidth_mbit: 100}\n", "p.yaml").coordinator);
  Profile p = parse_profile("coordinator: {up_mbit: 1000, down_mbit: 500, latency_ms: 0.1}\n", "p.yaml");
  ASSERT_TRUE(p.coordinator);
  EXPECT_EQ(p.coordinator->up_mbit, 1000);
  EXPECT_EQ(p.coordinator->down_mbit, 500);
  EXPECT_EQ(p.coordinator->latency_ms, 0.1);
  EXPECT_EQ(p.defaults, LinkSpec{});  // the nodes' links are not touched
}

// Every profile we ship parses; the three the issue names are there.
TEST(Profile, ShippedProfilesParse) {
  int n = 0;
  for (const auto& f : std::filesystem::directory_iterator(SIRAD_SOURCE_DIR "/deploy/profiles")) {
    if (f.path().extension() != ".yaml") continue;
    EXPECT_NO_THROW(load_profile(f.path().string())) << f.path();
    ++n;
  }
  EXPECT_GE(n, 3);
  EXPECT_EQ(load_profile(SIRAD_SOURCE_DIR "/deploy/profiles/office-mixed.yaml").for_node(3, "x").down_mbit, 100);
}

// The heterogeneous 16-node farm of issue 5's experiments: speeds 0.25x to 4x, links 10 Mbit/s
// to 1 Gbit/s, every node listed, no loss or disconnects.
TEST(Profile, Hetero16SpansItsSpeedsAndLinks) {
  Profile p = load_profile(SIRAD_SOURCE_DIR "/deploy/profiles/hetero-16.yaml");
  double slow = 1e9, fast = 0, thin = 1e9, wide = 0;
  for (uint32_t i = 0; i < 16; ++i) {
    LinkSpec l = p.for_node(i, "node");
    slow = std::min(slow, l.speed);
    fast = std::max(fast, l.speed);
    thin = std::min(thin, l.up_mbit);
    wide = std::max(wide, l.up_mbit);
    EXPECT_EQ(l.loss, 0.0) << i;
    EXPECT_LT(l.disconnect_at_s, 0.0) << i;
  }
  EXPECT_EQ(slow, 0.25);
  EXPECT_EQ(fast, 4.0);
  EXPECT_EQ(thin, 10.0);
  EXPECT_EQ(wide, 1000.0);
  EXPECT_EQ(p.slowdown(p.for_node(15, "n15")), 16.0);  // the fastest runs at real speed
}

// Bandwidth and latency: a 1 MB message on an 8 Mbit/s link with 10 ms latency arrives after
// 1 s + 10 ms; a second one sent at once queues behind it (store and forward).
TEST(LinkModel, BandwidthQueuesAndLatencyAdds) {
  LinkModel link(8, 10, 0, 0, 1);
  EXPECT_NEAR(link.deliver(0, 1000000), 1.010, 1e-12);
  EXPECT_NEAR(link.deliver(0, 1000000), 2.010, 1e-12);
  EXPECT_NEAR(link.deliver(5, 1000), 5.011, 1e-12);
  LinkModel none;
  EXPECT_FALSE(none.shaped());
  EXPECT_EQ(none.deliver(3, 1 << 30), 3);
}

// Jitter: the delay is uniform in latency +- jitter, so its mean is the latency (the mean of n
// uniform draws of half-width J has standard deviation J / sqrt(3 n): 4 of them bound it), and
// messages never overtake each other.
TEST(LinkModel, JitterIsUniformAroundTheLatencyAndKeepsOrder) {
  LinkModel link(0, 10, 4, 0, 7);
  const int n = 20000;
  double sum = 0, last = 0, lo = 1, hi = 0;
  for (int i = 0; i < n; ++i) {
    double t = i * 1.0;  // far apart: order never binds
    double d = link.deliver(t, 100) - t;
    sum += d;
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  EXPECT_NEAR(sum / n, 0.010, 4 * 0.004 / std::sqrt(3.0 * n));
  EXPECT_GE(lo, 0.006);
  EXPECT_LE(hi, 0.014);
  EXPECT_LT(lo, 0.0061);
  EXPECT_GT(hi, 0.0139);
  LinkModel burst(0, 10, 9, 0, 3);
  for (int i = 0; i < 1000; ++i) {
    double a = burst.deliver(i * 1e-4, 100);
    EXPECT_GE(a, last);
    last = a;
  }
}

// Loss: a one-packet message is lost with probability p per try and each loss costs a
// retransmission timeout (0.2 s on a short link), so the extra delay is 0.2 G with G geometric,
// mean p / (1 - p) and variance p / (1 - p)^2: over n messages the mean is within 4 standard
// errors. A long message needs fast-retransmit rounds of one RTT instead.
TEST(LinkModel, LossCostsRetransmissionTimeouts) {
  const double p = 0.1;
  LinkModel link(0, 1, 0, p, 11);
  const int n = 40000;
  double extra = 0;
  for (int i = 0; i < n; ++i) extra += link.deliver(i * 10.0, 100) - i * 10.0 - 0.001;
  double rounds = extra / n / LinkModel::kMinRto;
  double mean = p / (1 - p), sd = std::sqrt(p) / (1 - p);
  EXPECT_NEAR(rounds, mean, 4 * sd / std::sqrt(n));
  // 100 packets at p = 0.1: they leave at the Mathis rate (below), then almost surely some
  // loss, each round one RTT (2 ms; P(more than 10 rounds) = 1 - (1 - 0.1^10)^100 ~ 1e-8).
  LinkModel big(0, 1, 0, p, 12);
  double sent = 100 * LinkModel::kSegmentBytes * 8 / (1.22 * 1448 * 8 / (0.002 * std::sqrt(p)));
  double d = big.deliver(0, 100 * LinkModel::kSegmentBytes) - 0.001 - sent;
  EXPECT_GT(d, 0.0019);
  EXPECT_LT(d, 0.0201);
}

// With loss, the Mathis bound caps throughput: 1.22 * 1448 * 8 / (RTT sqrt(p)) bit/s.
TEST(LinkModel, LossCapsThroughputByTheMathisBound) {
  LinkModel link(1000, 5, 0, 0.01, 5);  // RTT 10 ms, p 1%: about 14.1 Mbit/s, not 1000
  double cap = 1.22 * 1448 * 8 / (0.010 * 0.1);
  double t = 0;
  for (int i = 0; i < 100; ++i) t = link.deliver(0, 1000000);  // 100 MB queued at once
  // The last byte leaves at 8e8 / cap seconds; retransmission rounds add a little on top.
  EXPECT_GT(t, 8e8 / cap);
  EXPECT_LT(t, 8e8 / cap * 1.1);
}

}  // namespace
}  // namespace sirad::emulation
