// sirad: the image phase's decisions (see image_phase.h).
#include "cluster/image_phase.h"

#include <algorithm>

namespace sirad::cluster {

ImagePhase::ImagePhase(int width, int height, int spp, DeadlineRules rules, uint32_t wait_for)
    : spp_(spp), plan_(width, height, kTileSide), deadlines_(rules), wait_for_(wait_for) {}

void ImagePhase::join(uint32_t node) {
  rendering_.insert(node);
  deadlines_.clear(node);
}

std::vector<ImagePhase::Order> ImagePhase::next_work(double now) {
  std::vector<Order> out;
  for (uint32_t n : rendering_)
    for (TileGrant& g : plan_.top_up(n)) {
      uint64_t pixels = 0;
      for (const Range& r : g.tiles)
        for (uint64_t t = r.first; t < r.last; ++t) pixels += plan_.grid().rect(t).pixels();
      auto measured = tile_s_.find(n);
      const double bound = measured != tile_s_.end() ? kTilesBound * measured->second
                                                     : deadlines_.rules().first_grant_s +
                                                           kFirstSampleS * static_cast<double>(pixels) * spp_;
      deadlines_.add(n, g.id, now, bound);
      out.push_back({n, std::move(g)});
    }
  return out;
}

std::optional<double> ImagePhase::take_result(uint32_t node, uint64_t grant, const std::vector<Range>& done,
                                              const std::vector<std::string>& frames, double busy_s, double max_busy_s,
                                              double now, const TileCheck& check) {
  plan_.accept(node, grant, done, frames, check);
  deadlines_.settle(node, grant);
  // Accepted, the PIXELS holds one frame per tile.
  double& tile_s = tile_s_[node];
  if (busy_s >= 0 && busy_s <= max_busy_s)
    tile_s = std::max(tile_s, busy_s / static_cast<double>(std::max<std::size_t>(1, frames.size())));
  std::vector<uint32_t> unmeasured;
  for (uint32_t n : rendering_)
    if (!tile_s_.count(n)) unmeasured.push_back(n);
  if (deadlines_.tighten(unmeasured, now, tile_s)) return tile_s;
  return std::nullopt;
}

void ImagePhase::drop(uint32_t node) {
  plan_.abandon(node);
  deadlines_.clear(node);
  rendering_.erase(node);
}

bool ImagePhase::render_here() {
  if (wait_for_ > 0 && rendering_.size() >= wait_for_) wait_for_ = 0;
  return rendering_.empty() && wait_for_ == 0;
}

}  // namespace sirad::cluster
