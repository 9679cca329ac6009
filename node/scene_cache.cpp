// sirad: a node's scene cache (node/scene_cache.h).
#include "node/scene_cache.h"

#include <algorithm>
#include <filesystem>
#include <system_error>

#include "scene/encoding.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace sirad::node {

namespace fs = std::filesystem;

namespace {
constexpr std::string_view kSuffix = ".scene";
// A folder of many unrelated files is not searched without end.
constexpr std::size_t kMaxListed = 4096;
}  // namespace

SceneCache::SceneCache(std::string dir) : dir_(std::move(dir)) {
  if (dir_.empty()) return;
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (!fs::is_directory(dir_, ec)) fail("--scene-cache {}: not a folder, and cannot be made one", dir_);
}

std::string SceneCache::path_of(const std::string& hash) const { return (fs::path(dir_) / (hash + std::string(kSuffix))).string(); }

std::vector<std::string> SceneCache::disk_hashes() const {
  std::vector<std::pair<fs::file_time_type, std::string>> found;
  if (dir_.empty()) return {};
  std::error_code ec;
  fs::directory_iterator it(dir_, ec), end;
  for (std::size_t seen = 0; !ec && it != end && seen < kMaxListed; it.increment(ec), ++seen) {
    const std::string name = it->path().filename().string();
    if (name.size() != 32 + kSuffix.size() || !name.ends_with(kSuffix)) continue;
    const std::string hash = name.substr(0, 32);
    std::error_code e2;
    if (!is_scene_hash(hash) || !it->is_regular_file(e2)) continue;
    found.emplace_back(it->last_write_time(e2), hash);
  }
  std::sort(found.begin(), found.end(), std::greater<>());
  std::vector<std::string> hashes;
  for (auto& f : found) hashes.push_back(std::move(f.second));
  return hashes;
}

std::vector<std::string> SceneCache::hashes() const {
  std::vector<std::string> out;
  for (const Entry& e : memory_) out.push_back(e.hash);
  for (std::string& h : disk_hashes()) {
    if (out.size() >= kMaxMemoryScenes + kMaxDiskScenes) break;
    if (std::find(out.begin(), out.end(), h) == out.end()) out.push_back(std::move(h));
  }
  return out;
}

void SceneCache::remember(std::string hash, std::string bytes) {
  memory_bytes_ += bytes.size();
  memory_.push_front({std::move(hash), std::move(bytes)});
  while (memory_.size() > kMaxMemoryScenes || (memory_bytes_ > kMaxMemoryBytes && memory_.size() > 1)) {
    memory_bytes_ -= memory_.back().bytes.size();
    memory_.pop_back();
  }
}

std::optional<std::string> SceneCache::get(const std::string& hash) {
  if (!is_scene_hash(hash)) return std::nullopt;
  for (auto it = memory_.begin(); it != memory_.end(); ++it)
    if (it->hash == hash) {
      memory_.splice(memory_.begin(), memory_, it);  // most recently used
      return memory_.front().bytes;
    }
  if (dir_.empty()) return std::nullopt;
  const std::string path = path_of(hash);
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  std::string bytes;
  try {
    bytes = read_regular_file(path, path, kMaxSceneBytes, "too large for a scene");
  } catch (const Error&) {
    drop(hash);
    return std::nullopt;
  }
  // The file is only a claim: its bytes must hash to its name.
  if (scene_bytes_hash(bytes) != hash) {
    drop(hash);
    return std::nullopt;
  }
  fs::last_write_time(path, fs::file_time_type::clock::now(), ec);  // most recently used stays longest
  remember(hash, bytes);
  return bytes;
}

std::string SceneCache::put(const std::string& bytes, std::string* error) {
  std::string hash = scene_bytes_hash(bytes);
  forget(hash);
  remember(hash, bytes);
  if (dir_.empty()) return hash;
  try {
    write_file_atomic(path_of(hash), bytes);
  } catch (const Error& e) {
    if (error) *error = e.what();
    return hash;
  }
  std::vector<std::string> on_disk = disk_hashes();
  for (std::size_t i = kMaxDiskScenes; i < on_disk.size(); ++i) {
    std::error_code ec;
    fs::remove(path_of(on_disk[i]), ec);
  }
  return hash;
}

void SceneCache::forget(const std::string& hash) {
  for (auto it = memory_.begin(); it != memory_.end(); ++it)
    if (it->hash == hash) {
      memory_bytes_ -= it->bytes.size();
      memory_.erase(it);
      return;
    }
}

void SceneCache::drop(const std::string& hash) {
  forget(hash);
  if (dir_.empty() || !is_scene_hash(hash)) return;
  std::error_code ec;
  fs::remove(path_of(hash), ec);
}

}  // namespace sirad::node
