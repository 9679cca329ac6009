// sirad tests: a node's scene cache (node/scene_cache.h): entries by the hash of their bytes, in
// memory and in a folder, each checked against its name when read, within bounds of its own.
#include <sys/stat.h>

#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "node/scene_cache.h"
#include "scene/encoding.h"
#include "util/error.h"

namespace {

namespace fs = std::filesystem;
using sirad::node::SceneCache;

fs::path fresh_dir(const std::string& name) {
  fs::path dir = fs::temp_directory_path() / fmt::format("sirad_cache_{}_{}", name, ::getpid());
  fs::remove_all(dir);
  return dir;
}

TEST(SceneCache, KeepsScenesByTheHashOfTheirBytes) {
  SceneCache cache;
  const std::string a = "scene a", b = "scene b";
  const std::string ha = cache.put(a);
  EXPECT_EQ(ha, sirad::scene_bytes_hash(a));
  EXPECT_TRUE(sirad::is_scene_hash(ha));
  EXPECT_NE(sirad::scene_bytes_hash(a), sirad::scene_bytes_hash(b));
  cache.put(b);
  EXPECT_EQ(cache.get(ha).value_or(""), a);
  EXPECT_FALSE(cache.get(sirad::scene_bytes_hash("scene c")));
  EXPECT_FALSE(cache.get("../../etc/passwd"));
  // Most recent first: a was read after b was stored.
  EXPECT_EQ(cache.hashes(), (std::vector<std::string>{ha, sirad::scene_bytes_hash(b)}));
}

TEST(SceneCache, MemoryHoldsAtMostItsBoundOfScenes) {
  SceneCache cache;
  std::vector<std::string> hashes;
  for (std::size_t i = 0; i < SceneCache::kMaxMemoryScenes + 3; ++i) hashes.push_back(cache.put(fmt::format("scene {}", i)));
  EXPECT_EQ(cache.hashes().size(), SceneCache::kMaxMemoryScenes);
  EXPECT_FALSE(cache.get(hashes.front()));  // the least recently used went first
  EXPECT_TRUE(cache.get(hashes.back()));
}

TEST(SceneCache, AFolderKeepsThemForTheNextProcess) {
  const fs::path dir = fresh_dir("disk");
  std::string h;
  {
    SceneCache cache(dir.string());
    h = cache.put("a scene on disk");
  }
  EXPECT_TRUE(fs::exists(dir / (h + ".scene")));
  SceneCache later(dir.string());
  EXPECT_EQ(later.hashes(), std::vector<std::string>{h});
  EXPECT_EQ(later.get(h).value_or(""), "a scene on disk");
  fs::remove_all(dir);
}

// A file whose bytes no longer hash to its name (damaged, or written by someone else) is
// dropped when read, never returned; files of other names are not looked at.
TEST(SceneCache, DamagedOrForeignFilesAreNeverUsed) {
  const fs::path dir = fresh_dir("damaged");
  std::string h, g;
  {
    SceneCache cache(dir.string());
    h = cache.put("the true scene");
    g = cache.put("another scene");
  }
  {
    std::fstream f(dir / (h + ".scene"), std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(3);
    f.put('X');
  }
  fs::copy_file(dir / (g + ".scene"), dir / (std::string(32, 'a') + ".scene"));  // a name that is not its hash
  std::ofstream(dir / "notes.txt") << "not a scene";
  std::ofstream(dir / (std::string(32, 'G') + ".scene")) << "not a hash name";
  ::mkfifo((dir / (std::string(32, 'b') + ".scene")).c_str(), 0600);  // never opened for a blocking read
  SceneCache cache(dir.string());
  const std::vector<std::string> listed = cache.hashes();
  EXPECT_EQ(listed.size(), 3u);  // h, g and the misnamed copy; the FIFO, the text and the bad name are not listed
  EXPECT_FALSE(cache.get(h));
  EXPECT_FALSE(fs::exists(dir / (h + ".scene")));
  EXPECT_FALSE(cache.get(std::string(32, 'a')));
  EXPECT_FALSE(cache.get(std::string(32, 'b')));
  EXPECT_EQ(cache.get(g).value_or(""), "another scene");
  fs::remove_all(dir);
}

TEST(SceneCache, TheFolderHoldsAtMostItsBoundOfScenes) {
  const fs::path dir = fresh_dir("bound");
  SceneCache cache(dir.string());
  for (std::size_t i = 0; i < SceneCache::kMaxDiskScenes + 4; ++i) cache.put(fmt::format("scene {}", i));
  std::size_t files = 0;
  for (const auto& f : fs::directory_iterator(dir)) files += f.path().extension() == ".scene";
  EXPECT_EQ(files, SceneCache::kMaxDiskScenes);
  fs::remove_all(dir);
}

// A folder that cannot take the file: the scene stays in memory and the write's failure is told.
TEST(SceneCache, AFailedWriteKeepsTheSceneInMemory) {
  const fs::path dir = fresh_dir("readonly");
  SceneCache cache(dir.string());
  fs::remove_all(dir);
  std::ofstream(dir) << "a file where the folder was";
  std::string why;
  const std::string h = cache.put("kept in memory", &why);
  EXPECT_FALSE(why.empty());
  EXPECT_EQ(cache.get(h).value_or(""), "kept in memory");
  fs::remove(dir);
  EXPECT_THROW(SceneCache(std::string("/proc/version/x")), sirad::Error);
}

}  // namespace
