// sirad: the image phase's tiles (cluster/tiles.h).
#include "cluster/tiles.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "proto/codec.h"
#include "util/check.h"
#include "util/error.h"

namespace sirad::cluster {

namespace {

constexpr int kMinTileSide = 8;

}  // namespace

TileGrid::TileGrid(int width, int height, int side) : width_(width), height_(height), side_(side) {
  if (width < 1 || height < 1 || width > kMaxImageSide || height > kMaxImageSide)
    fail("image {}x{} (1 to {} a side)", width, height, kMaxImageSide);
  if (side < kMinTileSide || side > static_cast<int>(proto::kMaxTileSide))
    fail("tile side {} ({} to {})", side, kMinTileSide, proto::kMaxTileSide);
  across_ = (width + side - 1) / side;
  down_ = (height + side - 1) / side;
}

TileRect TileGrid::rect(uint64_t t) const {
  if (t >= count()) fail("tile {} of {}", t, count());
  const int tx = static_cast<int>(t % static_cast<uint64_t>(across_)), ty = static_cast<int>(t / static_cast<uint64_t>(across_));
  return {tx * side_, ty * side_, std::min(width_, (tx + 1) * side_), std::min(height_, (ty + 1) * side_)};
}

std::string pack_tile(const GatherPasses& tile) {
  const std::size_t n = tile.combined.pixels.size();
  std::string frame(n * proto::kPixelBytes, '\0');
  char* at = frame.data();
  for (std::size_t i = 0; i < n; ++i)
    for (const Image* image : {&tile.direct, &tile.indirect, &tile.combined}) {
      const float v[3] = {image->pixels[i].x, image->pixels[i].y, image->pixels[i].z};
      std::memcpy(at, v, sizeof v);  // little-endian: the platforms sirad builds on
      at += sizeof v;
    }
  return frame;
}

namespace {

// A frame's values (9 floats a pixel), checked: its size is the tile's, every value finite.
std::vector<float> tile_values(const std::string& frame, const TileRect& rect) {
  if (frame.size() != rect.pixels() * proto::kPixelBytes)
    fail("a tile frame of {} bytes for {} pixels ({} bytes)", frame.size(), rect.pixels(), rect.pixels() * proto::kPixelBytes);
  std::vector<float> v(rect.pixels() * 9);
  std::memcpy(v.data(), frame.data(), frame.size());
  for (std::size_t i = 0; i < v.size(); ++i)
    if (!std::isfinite(v[i])) fail("a tile's pixel {} is not finite", i / 9);
  return v;
}

void place(const std::vector<float>& v, const TileRect& rect, GatherPasses& image) {
  std::size_t k = 0;
  for (int y = rect.y0; y < rect.y1; ++y)
    for (int x = rect.x0; x < rect.x1; ++x)
      for (Image* out : {&image.direct, &image.indirect, &image.combined}) {
        out->at(x, y) = glm::vec3(v[k], v[k + 1], v[k + 2]);
        k += 3;
      }
}

}  // namespace

void unpack_tile(const std::string& frame, const TileRect& rect, GatherPasses& image) {
  place(tile_values(frame, rect), rect, image);
}

TilePlan::TilePlan(int width, int height, int side)
    : grid_(width, height, side), ledger_(grid_.count()), passes_(GatherPasses::of_size(width, height)) {}

std::vector<TileGrant> TilePlan::top_up(uint32_t node) {
  std::vector<TileGrant> out;
  std::vector<TileGrant>& held = outstanding_[node];
  while (held.size() < kGrantsPerNode) {
    std::vector<Range> tiles = ledger_.grant(node, 1);
    if (tiles.empty()) break;
    held.push_back({next_id_++, std::move(tiles)});
    out.push_back(held.back());
  }
  return out;
}

void check_pixel(const float* sent, const GatherPasses& here, double floor, int x, int y) {
  static constexpr const char* kChannel[9] = {"direct r", "direct g", "direct b", "indirect r", "indirect g", "indirect b", "r", "g", "b"};
  const Image* passes[3] = {&here.direct, &here.indirect, &here.combined};
  for (int k = 0; k < 9; ++k) {
    const double a = sent[k], b = passes[k / 3]->at(0, 0)[k % 3];
    if (!(std::abs(a - b) <= kPixelTolerance * std::max(std::abs(a), std::abs(b)) + floor))
      fail("pixel ({}, {}) is not what it renders here: {} {} against {}", x, y, kChannel[k], a, b);
  }
}

void TilePlan::accept(uint32_t node, uint64_t grant, const std::vector<Range>& done, const std::vector<std::string>& frames,
                      const TileCheck& check) {
  auto held = outstanding_.find(node);
  if (held == outstanding_.end()) fail("PIXELS for grant {}, which is not outstanding", grant);
  auto g = std::find_if(held->second.begin(), held->second.end(), [&](const TileGrant& t) { return t.id == grant; });
  if (g == held->second.end()) fail("PIXELS for grant {}, which is not outstanding", grant);
  if (done != g->tiles) fail("PIXELS for grant {} names other tiles than granted", grant);
  std::vector<TileRect> rects;
  for (const Range& r : done)
    for (uint64_t t = r.first; t < r.last; ++t) rects.push_back(grid_.rect(t));
  if (frames.size() != rects.size()) fail("PIXELS for grant {}: {} frames for {} tiles", grant, frames.size(), rects.size());
  // Every frame checked before any is placed, so a bad last tile leaves nothing placed.
  std::vector<std::vector<float>> values;
  for (std::size_t i = 0; i < rects.size(); ++i) values.push_back(tile_values(frames[i], rects[i]));
  if (check)
    for (std::size_t i = 0; i < rects.size(); ++i) check(rects[i], values[i]);
  for (std::size_t i = 0; i < rects.size(); ++i) place(values[i], rects[i], passes_);
  for (const Range& r : done) ledger_.done(node, r);
  held->second.erase(g);
}

void TilePlan::abandon(uint32_t node) {
  if (auto held = outstanding_.find(node); held != outstanding_.end())
    for (const TileGrant& g : held->second)
      for (const Range& r : g.tiles)
        for (uint64_t t = r.first; t < r.last; ++t)
          if (++losses_[t] >= kMaxTileLosses && !poisoned_) poisoned_ = t;
  ledger_.abandon(node);
  outstanding_.erase(node);
  here_from_ = 0;  // tiles are free again
}

std::optional<uint64_t> TilePlan::take_here() {
  for (; here_from_ < grid_.count(); ++here_from_)
    if (!losses_.count(here_from_) && ledger_.grant_index(kHere, here_from_)) return here_from_++;
  return std::nullopt;
}

void TilePlan::place_here(uint64_t t, const GatherPasses& tile) {
  const TileRect r = grid_.rect(t);
  SIRAD_CHECK(tile.combined.width == r.x1 - r.x0 && tile.combined.height == r.y1 - r.y0, "tile {}: passes of another size", t);
  ledger_.done(kHere, {t, t + 1});
  unpack_tile(pack_tile(tile), r, passes_);
}

std::size_t TilePlan::outstanding(uint32_t node) const {
  auto it = outstanding_.find(node);
  return it == outstanding_.end() ? 0 : it->second.size();
}

uint64_t TilePlan::tiles_done_by(uint32_t node) const {
  uint64_t n = 0;
  for (const Range& r : ledger_.done_by(node)) n += r.size();
  return n;
}

}  // namespace sirad::cluster
