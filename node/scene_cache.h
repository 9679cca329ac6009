// sirad: the scenes a node holds, named by the XXH3-128 of their encoded bytes (scene/encoding.h
// scene_bytes_hash), so a coordinator sends a scene to a node once (Hello.scene_hashes,
// proto/PROTOCOL.md 3.1). In memory for the process's life, and in a folder when the node is
// given one (`sirad-node --scene-cache DIR`), so a restarted node still holds them.
//
// Every entry is checked against its name when it is read (memory entries when stored): a
// damaged, renamed or foreign file is dropped, never used. Bounded by limits of its own: at
// most kMaxMemoryScenes and kMaxMemoryBytes in memory (least recently used dropped first), at
// most kMaxDiskScenes files in the folder (oldest dropped), each at most kMaxSceneBytes; files
// whose names are not 32 hex digits and ".scene" are not looked at.
#pragma once
#include <cstddef>
#include <list>
#include <optional>
#include <string>
#include <vector>

#include "util/limits.h"

namespace sirad::node {

class SceneCache {
 public:
  static constexpr std::size_t kMaxMemoryScenes = 4;
  static constexpr std::size_t kMaxMemoryBytes = std::size_t{1} << 30;
  static constexpr std::size_t kMaxDiskScenes = 16;

  // `dir` empty: memory only. The folder is created when missing; throws sirad::Error when it
  // cannot be (or is not a folder).
  explicit SceneCache(std::string dir = {});

  // The hashes held, most recent first (memory, then the folder), at most kMaxMemoryScenes +
  // kMaxDiskScenes: what HELLO lists.
  std::vector<std::string> hashes() const;

  // The scene whose bytes hash to `hash`, or none (not held, or its file was damaged: dropped).
  std::optional<std::string> get(const std::string& hash);

  // Keeps `bytes` under their own hash (computed here), in memory and in the folder (written
  // atomically; a failed write is reported by the return value, the memory entry stays).
  // Returns the hash, or an error text in `error`.
  std::string put(const std::string& bytes, std::string* error = nullptr);

  // Drops `hash` from memory and the folder.
  void drop(const std::string& hash);

 private:
  struct Entry {
    std::string hash, bytes;
  };
  std::string path_of(const std::string& hash) const;
  std::vector<std::string> disk_hashes() const;  // newest first, valid names only
  void remember(std::string hash, std::string bytes);  // in memory, most recent first
  void forget(const std::string& hash);                // from memory only

  std::string dir_;
  std::list<Entry> memory_;  // most recently used first
  std::size_t memory_bytes_ = 0;
};

}  // namespace sirad::node
