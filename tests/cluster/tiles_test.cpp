// sirad tests: the image phase's bookkeeping (cluster/tiles.h): tiles cover the image once,
// PIXELS frames round-trip, and a TilePlan grants, checks and places tiles as the ledger does
// bundles: nothing placed from a bad message, a dropped node's tiles granted again.
#include <cmath>
#include <cstring>
#include <limits>

#include <gtest/gtest.h>

#include "cluster/tiles.h"
#include "proto/codec.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "util/error.h"

namespace sirad::cluster {
namespace {

// Passes of w x h whose pixel (x, y) holds distinct values per pass (x + 1000 y + pass offset).
GatherPasses numbered(int w, int h, int x0 = 0, int y0 = 0) {
  GatherPasses p;
  float offset = 0;
  for (Image* image : {&p.direct, &p.indirect, &p.combined}) {
    image->width = w;
    image->height = h;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) image->pixels.push_back(glm::vec3(float(x0 + x) + 1000.0f * float(y0 + y) + offset, 1, 2));
    offset += 0.25f;
  }
  return p;
}

TEST(Tiles, TheGridCoversTheImageOnceWithEdgesCut) {
  const TileGrid g(70, 33, 32);
  EXPECT_EQ(g.count(), 3u * 2u);
  std::vector<int> covered(70 * 33, 0);
  for (uint64_t t = 0; t < g.count(); ++t) {
    const TileRect r = g.rect(t);
    for (int y = r.y0; y < r.y1; ++y)
      for (int x = r.x0; x < r.x1; ++x) ++covered[static_cast<std::size_t>(y * 70 + x)];
  }
  for (int c : covered) ASSERT_EQ(c, 1);
  EXPECT_EQ(g.rect(2).x1 - g.rect(2).x0, 6);   // the last of a row, cut at x = 70
  EXPECT_EQ(g.rect(5).y1 - g.rect(5).y0, 1);   // the last row, cut at y = 33
  EXPECT_EQ(g.rect(3).x0, 0);                  // rows from the top left
  EXPECT_EQ(g.rect(3).y0, 32);
  EXPECT_THROW(g.rect(6), Error);
  EXPECT_THROW(TileGrid(70, 33, 7), Error);
  EXPECT_THROW(TileGrid(70, 33, static_cast<int>(proto::kMaxTileSide) + 1), Error);
  EXPECT_THROW(TileGrid(0, 33, 32), Error);
  EXPECT_THROW(TileGrid(16385, 33, 32), Error);
}

TEST(Tiles, APixelsFrameRoundTripsIntoItsPlace) {
  const TileGrid g(40, 40, 16);
  const TileRect r = g.rect(4);  // (16..32) x (16..32)
  const GatherPasses tile = numbered(r.x1 - r.x0, r.y1 - r.y0, r.x0, r.y0);
  const std::string frame = pack_tile(tile);
  EXPECT_EQ(frame.size(), r.pixels() * proto::kPixelBytes);
  GatherPasses image = numbered(40, 40);
  for (Image* i : {&image.direct, &image.indirect, &image.combined}) std::fill(i->pixels.begin(), i->pixels.end(), glm::vec3(-1));
  unpack_tile(frame, r, image);
  const GatherPasses want = numbered(40, 40);
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 40; ++x) {
      const bool inside = x >= r.x0 && x < r.x1 && y >= r.y0 && y < r.y1;
      ASSERT_EQ(image.direct.at(x, y), inside ? want.direct.at(x, y) : glm::vec3(-1));
      ASSERT_EQ(image.indirect.at(x, y), inside ? want.indirect.at(x, y) : glm::vec3(-1));
      ASSERT_EQ(image.combined.at(x, y), inside ? want.combined.at(x, y) : glm::vec3(-1));
    }
  EXPECT_THROW(unpack_tile(frame.substr(0, frame.size() - proto::kPixelBytes), r, image), Error);
}

TEST(Tiles, APlanGrantsTwoAtATimeAndPlacesWhatFits) {
  TilePlan plan(40, 20, 16);  // 3 x 2 tiles
  const std::vector<TileGrant> a = plan.top_up(0);
  ASSERT_EQ(a.size(), TilePlan::kGrantsPerNode);
  EXPECT_TRUE(plan.top_up(0).empty()) << "a node holds two grants at most";
  const std::vector<TileGrant> b = plan.top_up(1);
  ASSERT_EQ(b.size(), 2u);
  auto frames_of = [&](const TileGrant& g) {
    std::vector<std::string> f;
    for (const Range& r : g.tiles)
      for (uint64_t t = r.first; t < r.last; ++t) {
        const TileRect rect = plan.grid().rect(t);
        f.push_back(pack_tile(numbered(rect.x1 - rect.x0, rect.y1 - rect.y0, rect.x0, rect.y0)));
      }
    return f;
  };
  // Refused, nothing placed: another node's grant, other tiles than granted, a short frame, a NaN.
  EXPECT_THROW(plan.accept(1, a[0].id, a[0].tiles, frames_of(a[0])), Error);
  EXPECT_THROW(plan.accept(0, a[0].id, b[0].tiles, frames_of(b[0])), Error);
  std::vector<std::string> short_frame = frames_of(a[0]);
  short_frame[0].pop_back();
  EXPECT_THROW(plan.accept(0, a[0].id, a[0].tiles, short_frame), Error);
  std::vector<std::string> nan_frame = frames_of(a[0]);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan_frame[0].data() + 4 * proto::kPixelBytes + 8, &nan, sizeof nan);
  EXPECT_THROW(plan.accept(0, a[0].id, a[0].tiles, nan_frame), Error);
  // A check that refuses the tile's pixels (the coordinator's spot check): nothing placed.
  int checked = 0;
  EXPECT_THROW(plan.accept(0, a[0].id, a[0].tiles, frames_of(a[0]),
                           [&](const TileRect& r, const std::vector<float>& v) {
                             ++checked;
                             EXPECT_EQ(v.size(), 9u * r.pixels());
                             fail("not what it renders here");
                           }),
               Error);
  EXPECT_EQ(checked, 1);
  EXPECT_EQ(plan.done_count(), 0u);
  for (const glm::vec3& v : plan.passes().combined.pixels) ASSERT_EQ(v, glm::vec3(0)) << "nothing placed";
  // Accepted once; the same grant again is refused (nothing counted twice).
  plan.accept(0, a[0].id, a[0].tiles, frames_of(a[0]));
  EXPECT_THROW(plan.accept(0, a[0].id, a[0].tiles, frames_of(a[0])), Error);
  EXPECT_EQ(plan.done_count(), 1u);
  EXPECT_EQ(plan.outstanding(0), 1u);
  // Node 1 is dropped: its two tiles go back, and node 0 is granted them.
  plan.abandon(1);
  EXPECT_THROW(plan.accept(1, b[0].id, b[0].tiles, frames_of(b[0])), Error);
  std::vector<TileGrant> again = plan.top_up(0);
  ASSERT_EQ(again.size(), 1u);
  EXPECT_EQ(again[0].tiles, b[0].tiles) << "the lowest free tile: node 1's first";
  plan.accept(0, a[1].id, a[1].tiles, frames_of(a[1]));
  plan.accept(0, again[0].id, again[0].tiles, frames_of(again[0]));
  // The rest rendered here, as the coordinator does with no node left (node 0 holds nothing
  // now): tiles 4 and 5, not tile 3, which was lost with node 1 and waits for a node.
  EXPECT_EQ(plan.outstanding(0), 0u);
  std::vector<uint64_t> here;
  while (std::optional<uint64_t> t = plan.take_here()) {
    here.push_back(*t);
    const TileRect r = plan.grid().rect(*t);
    plan.place_here(*t, numbered(r.x1 - r.x0, r.y1 - r.y0, r.x0, r.y0));
  }
  EXPECT_EQ(here, (std::vector<uint64_t>{4, 5}));
  EXPECT_FALSE(plan.finished());
  const std::vector<TileGrant> c = plan.top_up(0);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].tiles, (std::vector<Range>{{3, 4}}));
  plan.accept(0, c[0].id, c[0].tiles, frames_of(c[0]));
  EXPECT_TRUE(plan.finished());
  EXPECT_EQ(plan.passes().combined.pixels, numbered(40, 20).combined.pixels);
  EXPECT_EQ(plan.passes().direct.pixels, numbered(40, 20).direct.pixels);
  EXPECT_EQ(plan.passes().indirect.pixels, numbered(40, 20).indirect.pixels);
  EXPECT_EQ(plan.tiles_done_by(0), 4u);
}

// A tile whose node is lost while it holds it goes back; one lost with kMaxTileLosses nodes is
// named (the coordinator then ends the image instead of handing it to a next node to crash).
// The coordinator never renders a lost tile itself: it waits for a node. Tiles a node sent are
// not counted, nor a node dropped holding nothing.
TEST(Tiles, ATileLostWithThreeNodesIsNamed) {
  TilePlan plan(40, 20, 8);  // 5 x 3 tiles
  for (uint32_t node = 0; node < TilePlan::kMaxTileLosses; ++node) {
    EXPECT_FALSE(plan.poisoned()) << node;
    const std::vector<TileGrant> g = plan.top_up(node);
    ASSERT_EQ(g.size(), 2u);
    EXPECT_EQ(g[0].tiles, (std::vector<Range>{{0, 1}}));  // the lowest free tiles again
    plan.abandon(node);
    plan.abandon(node);  // a second drop of the node holds nothing: no loss
  }
  ASSERT_TRUE(plan.poisoned());
  EXPECT_EQ(*plan.poisoned(), 0u);
  // With no node left, the coordinator takes every tile but the two lost ones (0 and 1).
  std::vector<uint64_t> here;
  while (std::optional<uint64_t> t = plan.take_here()) {
    here.push_back(*t);
    const TileRect r = plan.grid().rect(*t);
    plan.place_here(*t, numbered(r.x1 - r.x0, r.y1 - r.y0, r.x0, r.y0));
  }
  EXPECT_EQ(here, (std::vector<uint64_t>{2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14}));
  EXPECT_FALSE(plan.finished());
  const std::vector<TileGrant> last = plan.top_up(7);  // a node joins: it is granted them
  ASSERT_EQ(last.size(), 2u);
  EXPECT_EQ(last[0].tiles, (std::vector<Range>{{0, 1}}));
  EXPECT_EQ(last[1].tiles, (std::vector<Range>{{1, 2}}));
  TilePlan other(40, 20, 8);
  for (uint32_t node = 0; node < 2 * TilePlan::kMaxTileLosses; ++node) {
    const std::vector<TileGrant> g = other.top_up(node);
    const TileRect r = other.grid().rect(g[0].tiles[0].first);
    other.accept(node, g[0].id, g[0].tiles, {pack_tile(numbered(r.x1 - r.x0, r.y1 - r.y0, r.x0, r.y0))});  // sent: not lost
    other.abandon(node);  // its second tile lost once: the next node is granted it first and sends it
  }
  EXPECT_FALSE(other.poisoned());
}

// A node's pixel against the same pixel rendered here: equal, or within 1 % relative per
// channel (another machine's rounding), passes; a channel 2 % off, or off by more than the floor
// where here's is 0, is refused with the pixel and the channel named.
TEST(Tiles, ASpotCheckedPixelMustBeWhatItRendersHere) {
  GatherPasses here = GatherPasses::of_size(1, 1);
  here.direct.at(0, 0) = glm::vec3(0.5f, 0.25f, 0.0f);
  here.indirect.at(0, 0) = glm::vec3(0.1f, 0.2f, 0.3f);
  here.combined.at(0, 0) = here.direct.at(0, 0) + here.indirect.at(0, 0);
  auto sent = [&] {
    std::vector<float> v;
    for (const Image* p : {&here.direct, &here.indirect, &here.combined})
      for (int c = 0; c < 3; ++c) v.push_back(p->at(0, 0)[c]);
    return v;
  };
  std::vector<float> v = sent();
  EXPECT_NO_THROW(check_pixel(v.data(), here, 1e-6, 3, 4));
  v[4] *= 1.009f;  // indirect g, 0.9 % off
  EXPECT_NO_THROW(check_pixel(v.data(), here, 1e-6, 3, 4));
  v[4] = sent()[4] * 1.02f;
  try {
    check_pixel(v.data(), here, 1e-6, 3, 4);
    ADD_FAILURE() << "a channel 2 % off passed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("pixel (3, 4)"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("indirect g"), std::string::npos) << e.what();
  }
  v = sent();
  v[2] = 5e-7f;  // direct b: here 0, within the floor
  EXPECT_NO_THROW(check_pixel(v.data(), here, 1e-6, 0, 0));
  v[2] = 2e-6f;
  EXPECT_THROW(check_pixel(v.data(), here, 1e-6, 0, 0), Error);
}

}  // namespace
}  // namespace sirad::cluster
