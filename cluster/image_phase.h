// sirad: the image phase's decisions (PROTOCOL.md section 3.4), free of sockets and clocks: which
// tiles go to which node and when each grant is due, what a node's PIXELS do to the plan, what a
// lost node gives back, and when no node is left so that the coordinator renders tiles itself.
// Fed messages and the time (seconds on the caller's clock), it answers with work; the real
// coordinator drives it over ZeroMQ (coordinator/coordinator.cpp), its tests without sockets.
#pragma once
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "cluster/deadlines.h"
#include "cluster/tiles.h"

namespace sirad::cluster {

class ImagePhase {
 public:
  // The tile side in pixels: 1,024 pixels a tile, so a 512 x 512 image has 256 tiles to spread
  // and a tile's PIXELS is 36 KiB.
  static constexpr int kTileSide = 32;
  // A grant of tiles is due `kTilesBound` times the node's longest time per tile so far after
  // it starts; before the node has sent any, the rules' first_grant_s and kFirstSampleS a sample.
  static constexpr double kTilesBound = 8;
  static constexpr double kFirstSampleS = 20e-6;

  // The image of `width` x `height` at `spp` samples per pixel. `wait_for` nodes must be rendering
  // before any tile is rendered here (a resumed run none of whose nodes is here yet: 0 when nodes
  // are already rendering).
  ImagePhase(int width, int height, int spp, DeadlineRules rules, uint32_t wait_for);

  // `node` renders tiles from now (its IMAGE went out).
  void join(uint32_t node);
  bool rendering(uint32_t node) const { return rendering_.count(node) > 0; }
  std::size_t rendering_nodes() const { return rendering_.size(); }

  // The TILES grants to send at `now`: every rendering node topped up to
  // TilePlan::kGrantsPerNode grants, each due from now.
  struct Order {
    uint32_t node = 0;
    TileGrant grant;
  };
  std::vector<Order> next_work(double now);

  // `node`'s PIXELS for `grant` at `now` (`busy_s`: its own word for the time the tiles took,
  // taken within [0, max_busy_s]); the tiles placed once `check` passes them
  // (TilePlan::accept). Throws sirad::Error naming the problem; the caller drops the node.
  // Returns the time per tile the first tiles of the nodes that have sent none are now held
  // to, when that tightened a due time (Deadlines::tighten).
  std::optional<double> take_result(uint32_t node, uint64_t grant, const std::vector<Range>& done,
                                    const std::vector<std::string>& frames, double busy_s, double max_busy_s, double now,
                                    const TileCheck& check);

  // At `at`: why `node`'s tiles are overdue, or "".
  std::string overdue(uint32_t node, double at) const { return deadlines_.overdue(node, at); }
  // `node` renders no more: its outstanding tiles go back (those it sent stay). Then
  // poisoned() may name a tile lost with too many nodes (the image cannot be made).
  void drop(uint32_t node);
  std::optional<uint64_t> poisoned() const { return plan_.poisoned(); }

  // Whether the coordinator renders tiles itself now: no node renders, and none is awaited.
  bool render_here();
  std::optional<uint64_t> take_here() { return plan_.take_here(); }
  void place_here(uint64_t t, const GatherPasses& tile) { plan_.place_here(t, tile); }

  bool finished() const { return plan_.finished(); }
  uint64_t tiles() const { return plan_.grid().count(); }
  uint64_t tiles_done() const { return plan_.done_count(); }
  uint64_t tiles_by(uint32_t node) const { return plan_.tiles_done_by(node); }
  const TileGrid& grid() const { return plan_.grid(); }
  GatherPasses& passes() { return plan_.passes(); }

 private:
  int spp_;
  TilePlan plan_;
  Deadlines deadlines_;
  uint32_t wait_for_;
  std::set<uint32_t> rendering_;
  std::map<uint32_t, double> tile_s_;  // per node that has sent tiles: its longest time per tile
};

}  // namespace sirad::cluster
