// sirad: the final gather's irradiance cache records and the store that makes each one once
// (render/gather.cpp's own: no other file includes it).
#pragma once
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>
#include <unordered_map>

#include <glm/vec3.hpp>

#include "scene/rays.h"
#include "util/error.h"

namespace sirad {

// A record of the irradiance cache: the indirect light (before rho) reflected at the point x
// (normal n) a raster point of the view sees, from record_rays() gather rays, and the least
// distance one of them went (infinity if all left the scene). Not valid where the raster point
// sees no reflecting surface.
struct CacheRecord {
  glm::dvec3 x{0.0}, n{0.0}, e{0.0};
  double r = 0.0;
  double emitters = 0.0;  // the share of the rays that met an emitter
  bool valid = false;
};

// The records of one view, made where first needed, by whichever thread needs one first (a
// record depends only on the view, the seed and its raster point: any thread, tile or node makes
// the same). Sharded maps; a thread that needs a record another is making waits for it.
class RecordStore {
 public:
  template <class Make>
  const CacheRecord& get(uint64_t key, const Make& make) {
    Shard& shard = shards_[Rng::mix(key) % kShards];
    Slot* slot;
    bool mine = false;
    {
      std::lock_guard lock(shard.mutex);
      auto& p = shard.slots[key];
      if (!p) {
        p = std::make_unique<Slot>();
        mine = true;
      }
      slot = p.get();
    }
    if (mine) {
      try {
        slot->record = make();
      } catch (...) {
        slot->state.store(kFailed, std::memory_order_release);
        throw;
      }
      slot->state.store(kReady, std::memory_order_release);
      return slot->record;
    }
    for (int s; (s = slot->state.load(std::memory_order_acquire)) != kReady;) {
      if (s == kFailed) fail("final gather: a cache record could not be made");
      std::this_thread::yield();
    }
    return slot->record;
  }

 private:
  static constexpr int kMaking = 0, kReady = 1, kFailed = 2;
  static constexpr std::size_t kShards = 64;
  struct Slot {
    std::atomic<int> state{kMaking};
    CacheRecord record;
  };
  struct Shard {
    std::mutex mutex;
    std::unordered_map<uint64_t, std::unique_ptr<Slot>> slots;
  };
  std::array<Shard, kShards> shards_;
};

}  // namespace sirad
