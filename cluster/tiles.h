// sirad: the image phase's bookkeeping (PROTOCOL.md section 3.4), free of sockets and clocks:
// a final gather's image cut into square tiles, granted to nodes through a Ledger as bundles
// are (a dead node's tiles go back and are granted again; a tile is placed once), and the
// pixels a node sends back checked and placed. The coordinator drives it over ZeroMQ.
#pragma once
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "cluster/exchange.h"
#include "render/gather.h"

namespace sirad::cluster {

// The pixels [x0, x1) x [y0, y1) of one tile.
struct TileRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  std::size_t pixels() const { return static_cast<std::size_t>(x1 - x0) * static_cast<std::size_t>(y1 - y0); }
};

// A width x height image in `side` x `side` tiles, in rows from the top left; the last tile of
// a row or a column is cut at the image's edge.
class TileGrid {
 public:
  // Throws sirad::Error for an image outside 1..16384 a side or a side outside 8..kMaxTileSide.
  TileGrid(int width, int height, int side);
  uint64_t count() const { return static_cast<uint64_t>(across_) * static_cast<uint64_t>(down_); }
  // Tile `t` (< count(); throws sirad::Error beyond).
  TileRect rect(uint64_t t) const;
  int width() const { return width_; }
  int height() const { return height_; }
  int side() const { return side_; }

 private:
  int width_, height_, side_, across_, down_;
};

// A tile's pixels as one PIXELS frame (proto::kPixelBytes a pixel, rows from the top: the
// direct, indirect and combined r, g, b as little-endian floats), from passes of the tile's size.
std::string pack_tile(const GatherPasses& tile);
// A PIXELS frame into `image` (passes of the whole image) at `rect`. Throws sirad::Error, with
// `image` untouched, for a frame of the wrong size or a value that is not finite.
void unpack_tile(const std::string& frame, const TileRect& rect, GatherPasses& image);

// A node's pixel against the same pixel rendered here (`here`: passes of 1 x 1), for the
// coordinator's spot checks: a pixel depends only on the seed and its place (render/gather.h), so
// an honest node of the same build sends it bit for bit; another machine's arithmetic may send
// a sample that grazes an edge another way, which moves a pixel by that sample's share. Each
// channel of `sent` (9 floats: direct, indirect, combined r, g, b) must be within kPixelTolerance
// of here's, relative, or `floor` (the scene's radiance scale times 1e-6) absolute; throws
// sirad::Error naming the pixel (x, y) and the channel otherwise.
constexpr double kPixelTolerance = 0.01;
void check_pixel(const float* sent, const GatherPasses& here, double floor, int x, int y);

// A check of one tile's pixels before they are placed (its place and values, 9 floats a pixel,
// rows from the top); throws sirad::Error naming what is wrong.
using TileCheck = std::function<void(const TileRect& rect, const std::vector<float>& values)>;

// One TILES grant: its id and the tiles it names.
struct TileGrant {
  uint64_t id = 0;
  std::vector<Range> tiles;
};

// The tiles of one image: who has which, and the passes as they fill.
class TilePlan {
 public:
  // How many grants a node holds at once: one to render while the next waits in its queue.
  static constexpr std::size_t kGrantsPerNode = 2;

  // The image of `width` x `height` in tiles of `side`; blank passes.
  TilePlan(int width, int height, int side);
  const TileGrid& grid() const { return grid_; }

  // Grants (one tile each) for `node` until it holds kGrantsPerNode or no tile is left free.
  std::vector<TileGrant> top_up(uint32_t node);
  // `node`'s PIXELS for grant `grant`: `done` must be that grant's tiles, in order, and
  // `frames` their pixels (unpack_tile), which `check` (if given) passes. Everything is checked
  // before anything is placed; throws sirad::Error naming the first problem (a grant not
  // outstanding for the node, other tiles, a frame of the wrong size, a value not finite, what
  // `check` throws).
  void accept(uint32_t node, uint64_t grant, const std::vector<Range>& done, const std::vector<std::string>& frames,
              const TileCheck& check = nullptr);
  // `node` is gone: its outstanding tiles return to be granted again (those it sent stay), each
  // counting a loss.
  void abandon(uint32_t node);
  // A tile lost with kMaxTileLosses nodes (each gone, dead or dropped, while it held the tile):
  // one that may crash whoever renders it, which the image phase must not hand out again.
  static constexpr uint32_t kMaxTileLosses = 3;
  std::optional<uint64_t> poisoned() const { return poisoned_; }
  // For tiles no node is left to render: the next free tile (neither granted nor done) that no
  // node was lost with, now taken by the coordinator itself, or none; then place_here with its
  // passes (of the tile's size). A tile a node was lost with waits for a node: it may be what
  // crashed it, and it must not crash the coordinator.
  std::optional<uint64_t> take_here();
  void place_here(uint64_t t, const GatherPasses& tile);

  bool finished() const { return ledger_.finished(); }
  uint64_t done_count() const { return ledger_.done_count(); }
  std::size_t outstanding(uint32_t node) const;  // grants `node` holds
  uint64_t tiles_done_by(uint32_t node) const;
  GatherPasses& passes() { return passes_; }

 private:
  TileGrid grid_;
  Ledger ledger_;
  GatherPasses passes_;
  std::map<uint32_t, std::vector<TileGrant>> outstanding_;  // per node, oldest first
  std::map<uint64_t, uint32_t> losses_;                    // per tile lost at least once
  std::optional<uint64_t> poisoned_;
  uint64_t here_from_ = 0;  // take_here's scan: no tile below it is free and never lost
  uint64_t next_id_ = 1;
  static constexpr uint32_t kHere = 0xffffffffu;  // the ledger's node for tiles rendered here
};

}  // namespace sirad::cluster
