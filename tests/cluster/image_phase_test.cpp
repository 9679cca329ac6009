// sirad tests: grants' due times (cluster/deadlines.h) and the image phase's decisions
// (cluster/image_phase.h), without sockets or clocks: times are plain seconds handed in, so
// every due time below is exact arithmetic on the rules, not a measurement.
#include <gtest/gtest.h>

#include "cluster/deadlines.h"
#include "cluster/image_phase.h"
#include "util/error.h"

namespace sirad::cluster {
namespace {

// Seconds compared exactly where they are sums of small binary fractions; else within 1e-9.
constexpr double kEps = 1e-9;

TEST(Deadlines, AGrantIsDueAfterItsBoundAndQueuesBehindTheOneBefore) {
  Deadlines d({.slack_s = 10, .first_grant_s = 30, .unequal_first = 16});
  EXPECT_FALSE(d.holds(0));
  EXPECT_NEAR(d.add(0, 1, 100, 5), 115, kEps);  // now + bound + slack
  // Queued behind grant 1: it starts when grant 1's bound ends (its due time less the slack).
  EXPECT_NEAR(d.add(0, 2, 101, 5), 120, kEps);
  // Given later than that, it starts now.
  EXPECT_NEAR(d.add(0, 3, 200, 1), 211, kEps);
  EXPECT_EQ(d.overdue(0, 115), "") << "due at 115, not past it";
  EXPECT_EQ(d.overdue(0, 117.5), "grant 1 overdue by 2.5 s");
  d.settle(0, 1);
  EXPECT_EQ(d.overdue(0, 117.5), "") << "the oldest is grant 2 now, due at 120";
  EXPECT_EQ(d.overdue(0, 121), "grant 2 overdue by 1.0 s");
  d.settle(0, 99);  // no such grant: nothing changes
  EXPECT_EQ(d.overdue(0, 121), "grant 2 overdue by 1.0 s");
  d.clear(0);
  EXPECT_FALSE(d.holds(0));
  EXPECT_EQ(d.overdue(0, 1e9), "");
  EXPECT_EQ(d.overdue(7, 1e9), "") << "a node never granted is never overdue";
}

// Once a node measured its first grant at t, the k-th grant of each node still unmeasured is due
// within slack + (k + 1) 16 t of now, never later than it was.
TEST(Deadlines, AMeasuredFirstGrantTightensTheUnmeasuredOnly) {
  Deadlines d({.slack_s = 10, .first_grant_s = 30, .unequal_first = 16});
  d.add(0, 1, 0, 30);  // due 40
  d.add(0, 2, 0, 30);  // due 70
  d.add(1, 3, 0, 30);  // due 40
  d.add(2, 4, 0, 1);   // due 11: already sooner than any tightening gives
  EXPECT_TRUE(d.tighten({0, 2}, 5, 0.5));  // node 1 is the measured one
  EXPECT_EQ(d.overdue(0, 23), "");
  EXPECT_EQ(d.overdue(0, 23.5), "grant 1 overdue by 0.5 s");  // 5 + 10 + 16 x 0.5 = 23
  d.settle(0, 1);
  EXPECT_EQ(d.overdue(0, 31), "");
  EXPECT_EQ(d.overdue(0, 31.5), "grant 2 overdue by 0.5 s");  // 5 + 10 + 2 x 16 x 0.5 = 31
  EXPECT_EQ(d.overdue(1, 39), "") << "not in the list: untouched";
  EXPECT_EQ(d.overdue(2, 11.5), "grant 4 overdue by 0.5 s") << "never moved later";
  EXPECT_FALSE(d.tighten({2}, 5, 0.5)) << "nothing to move";
}

// Frames of every tile of `g` (zeros: what matters here is the bookkeeping).
std::vector<std::string> frames_of(const ImagePhase& phase, const TileGrant& g) {
  std::vector<std::string> out;
  for (const Range& r : g.tiles)
    for (uint64_t t = r.first; t < r.last; ++t) {
      const TileRect rect = phase.grid().rect(t);
      out.push_back(pack_tile(GatherPasses::of_size(rect.x1 - rect.x0, rect.y1 - rect.y0)));
    }
  return out;
}

// The tiles of an image go two grants at a time to each rendering node, each due after its
// bound: before the node has sent tiles, first_grant_s and 20 us a sample; after, 8 times its
// longest time per tile. A node's first PIXELS tightens the first tiles of the nodes that have
// sent none (Deadlines::tighten with its time per tile).
TEST(ImagePhase, GrantsTwoAtATimeEachDueAfterItsBound) {
  const DeadlineRules rules{.slack_s = 10, .first_grant_s = 30, .unequal_first = 16};
  ImagePhase phase(64, 64, 100, rules, 0);  // 2 x 2 tiles of 1,024 pixels
  EXPECT_TRUE(phase.render_here()) << "no node renders and none is awaited";
  phase.join(3);
  phase.join(5);
  EXPECT_FALSE(phase.render_here());
  std::vector<ImagePhase::Order> orders = phase.next_work(0);
  ASSERT_EQ(orders.size(), 4u);
  EXPECT_EQ(orders[0].node, 3u);
  EXPECT_EQ(orders[2].node, 5u);
  EXPECT_TRUE(phase.next_work(1).empty()) << "each holds two grants";
  // First bound: 30 + 20e-6 x 1,024 x 100 = 32.048 s; the second queued behind the first.
  const double first = 30 + 20e-6 * 1024 * 100;
  EXPECT_EQ(phase.overdue(3, first + 10), "");
  EXPECT_NE(phase.overdue(3, first + 10 + 1e-6), "");
  // Node 3 sends its first tile, 0.25 s of work: node 5's first grants tighten to
  // now + 10 + (k + 1) x 16 x 0.25.
  const std::optional<double> tightened =
      phase.take_result(3, orders[0].grant.id, orders[0].grant.tiles, frames_of(phase, orders[0].grant), 0.25, 1e9, 2, nullptr);
  ASSERT_TRUE(tightened);
  EXPECT_DOUBLE_EQ(*tightened, 0.25);
  EXPECT_EQ(phase.overdue(5, 16), "");
  EXPECT_EQ(phase.overdue(5, 16.5), "grant 3 overdue by 0.5 s");  // 2 + 10 + 16 x 0.25 = 16
  EXPECT_EQ(phase.tiles_by(3), 1u);
  EXPECT_EQ(phase.tiles_done(), 1u);
  // A busy time beyond the bound the caller gives is not taken: the time per tile stays.
  phase.take_result(3, orders[1].grant.id, orders[1].grant.tiles, frames_of(phase, orders[1].grant), 1e12, 1e9, 3, nullptr);
  EXPECT_TRUE(phase.next_work(3).empty()) << "no tile is left free: node 5 holds the last two";
  // Node 5 sends what is not its grant: refused, nothing placed; the caller drops it, and its
  // two tiles go to node 3, each due 8 x 0.25 s after it starts.
  EXPECT_THROW(phase.take_result(5, orders[0].grant.id, orders[0].grant.tiles, frames_of(phase, orders[0].grant), 0.1, 1e9, 4,
                                 nullptr),
               Error);
  EXPECT_EQ(phase.tiles_done(), 2u);
  phase.drop(5);
  EXPECT_FALSE(phase.rendering(5));
  EXPECT_EQ(phase.overdue(5, 1e9), "") << "a dropped node holds nothing due";
  orders = phase.next_work(10);
  ASSERT_EQ(orders.size(), 2u);
  EXPECT_EQ(orders[0].node, 3u);
  EXPECT_EQ(phase.overdue(3, 22), "");  // 10 + 8 x 0.25 + 10
  EXPECT_NE(phase.overdue(3, 22.5), "");
  for (const ImagePhase::Order& o : orders)
    phase.take_result(3, o.grant.id, o.grant.tiles, frames_of(phase, o.grant), 0.2, 1e9, 11, nullptr);
  EXPECT_TRUE(phase.finished());
  EXPECT_EQ(phase.tiles_by(3), 4u);
  EXPECT_EQ(phase.tiles_by(5), 0u);
}

// A resumed run's image waits for `wait_for` nodes before rendering here; with none left after
// that, the coordinator renders, but never a tile a node was lost with; a tile lost with three
// nodes is named.
TEST(ImagePhase, RendersHereOnlyWithNoNodeLeftAndNeverALostTile) {
  ImagePhase phase(64, 32, 4, DeadlineRules{}, 2);  // 2 tiles; wait for two nodes
  EXPECT_FALSE(phase.render_here()) << "waiting for two nodes";
  phase.join(0);
  EXPECT_FALSE(phase.render_here());
  phase.join(1);
  EXPECT_FALSE(phase.render_here()) << "two render";
  ASSERT_EQ(phase.next_work(0).size(), 2u);  // node 0 takes both tiles
  phase.drop(1);
  phase.drop(0);  // both tiles lost once
  EXPECT_TRUE(phase.render_here()) << "the wait is over once two joined; none is left";
  EXPECT_FALSE(phase.take_here()) << "both tiles were lost with a node: they wait for one";
  for (uint32_t n = 10; n < 10 + TilePlan::kMaxTileLosses - 1; ++n) {
    EXPECT_FALSE(phase.poisoned());
    phase.join(n);
    ASSERT_EQ(phase.next_work(0).size(), 2u);
    phase.drop(n);
  }
  ASSERT_TRUE(phase.poisoned());
  EXPECT_EQ(*phase.poisoned(), 0u);
}

}  // namespace
}  // namespace sirad::cluster
