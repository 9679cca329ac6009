// sirad: scene encoding for the wire, with every field checked on the way in.
#include "scene/encoding.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

#include <fmt/format.h>
#include <xxhash.h>

#include "util/error.h"

namespace sirad {

namespace {

// v2 adds a flags word per triangle (bit 0: Triangle::unlit, bit 1: Triangle::in_gap, bit 2:
// Triangle::whole); a scene
// without flags is written as v1, which nodes of every version read.
constexpr std::string_view kTag = "sirad-scene-v1", kTagFlags = "sirad-scene-v2";
static_assert(kTag.size() == kTagFlags.size());
constexpr uint32_t kUnlit = 1, kInGap = 2, kWhole = 4;
constexpr uint32_t kMaxCount = 1u << 26;  // at least the readers' own limits (scene_import.h)
static_assert(std::endian::native == std::endian::little, "the scene encoding is little-endian");

class Writer {
 public:
  void u32(uint32_t v) { raw(&v, 4); }
  void f32(float v) { raw(&v, 4); }
  void vec(const glm::vec3& v) {
    f32(v.x);
    f32(v.y);
    f32(v.z);
  }
  void str(const std::string& s) {
    u32(static_cast<uint32_t>(s.size()));
    out.append(s);
  }
  void raw(const void* p, std::size_t n) { out.append(static_cast<const char*>(p), n); }
  std::string out;
};

class Reader {
 public:
  Reader(std::string_view b, const std::string& label) : bytes_(b), label_(label) {}
  uint32_t u32(const char* what) {
    uint32_t v;
    take(&v, 4, what);
    return v;
  }
  float f32(const char* what) {
    float v;
    take(&v, 4, what);
    return v;
  }
  glm::vec3 vec(const char* what) {
    glm::vec3 v;
    v.x = f32(what);
    v.y = f32(what);
    v.z = f32(what);
    return v;
  }
  std::string str(const char* what) {
    uint32_t n = u32(what);
    if (n > 4096) fail("{}: {} of {} bytes (at most 4096)", label_, what, n);
    std::string s(n, '\0');
    take(s.data(), n, what);
    return s;
  }
  void take(void* p, std::size_t n, const char* what) {
    if (bytes_.size() - at_ < n) fail("{}: truncated at byte {} reading {}", label_, at_, what);
    std::memcpy(p, bytes_.data() + at_, n);
    at_ += n;
  }
  bool done() const { return at_ == bytes_.size(); }
  std::size_t at() const { return at_; }

 private:
  std::string_view bytes_;
  const std::string& label_;
  std::size_t at_ = 0;
};

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

std::string encode_scene(const Scene& scene) {
  Writer w;
  const bool flags = std::any_of(scene.triangles.begin(), scene.triangles.end(), [](const Triangle& t) { return t.unlit || t.in_gap || t.whole; });
  const std::string_view tag = flags ? kTagFlags : kTag;
  w.raw(tag.data(), tag.size());
  w.str(scene.name);
  w.u32(static_cast<uint32_t>(scene.materials.size()));
  for (const Material& m : scene.materials) {
    w.str(m.name);
    w.vec(m.reflectance);
    w.vec(m.emission);
  }
  w.u32(static_cast<uint32_t>(scene.triangles.size()));
  for (const Triangle& t : scene.triangles) {
    for (const auto& p : t.p) w.vec(p);
    w.u32(t.material);
    w.u32(t.source_line);
    if (flags) w.u32((t.unlit ? kUnlit : 0u) | (t.in_gap ? kInGap : 0u) | (t.whole ? kWhole : 0u));
  }
  w.vec(scene.background);
  w.u32(scene.camera ? 1u : 0u);
  if (scene.camera) {
    w.vec(scene.camera->eye);
    w.vec(scene.camera->look_at);
    w.vec(scene.camera->up);
    w.f32(scene.camera->vfov_deg);
  }
  return std::move(w.out);
}

Scene decode_scene(std::string_view bytes, const std::string& label) {
  const bool flags = bytes.substr(0, kTagFlags.size()) == kTagFlags;
  if (!flags && bytes.substr(0, kTag.size()) != kTag) fail("{}: not a sirad scene (no {} or {} tag)", label, kTag, kTagFlags);
  Reader r(bytes.substr(kTag.size()), label);
  Scene scene;
  scene.name = r.str("scene name");
  uint32_t materials = r.u32("material count");
  if (materials == 0 || materials > kMaxCount) fail("{}: {} materials", label, materials);
  bool emitter = false;
  for (uint32_t i = 0; i < materials; ++i) {
    Material m;
    m.name = r.str("material name");
    m.reflectance = r.vec("reflectance");
    m.emission = r.vec("emission");
    for (int c = 0; c < 3; ++c) {
      if (!(m.reflectance[c] >= 0.0f && m.reflectance[c] <= 1.0f))
        fail("{}: material {} reflectance {} outside [0, 1]", label, i, m.reflectance[c]);
      if (!(m.emission[c] >= 0.0f) || !std::isfinite(m.emission[c]))
        fail("{}: material {} emission {} is not finite and non-negative", label, i, m.emission[c]);
      emitter = emitter || m.emission[c] > 0.0f;
    }
    scene.materials.push_back(std::move(m));
  }
  uint32_t triangles = r.u32("triangle count");
  if (triangles == 0 || triangles > kMaxCount) fail("{}: {} triangles", label, triangles);
  if (static_cast<uint64_t>(triangles) * (flags ? 48 : 44) > bytes.size()) fail("{}: truncated: {} triangles announced", label, triangles);
  scene.triangles.resize(triangles);
  for (uint32_t i = 0; i < triangles; ++i) {
    Triangle& t = scene.triangles[i];
    for (auto& p : t.p) {
      p = r.vec("vertex");
      if (!finite(p)) fail("{}: triangle {} has a non-finite vertex", label, i);
    }
    t.material = r.u32("material index");
    t.source_line = r.u32("source line");
    if (t.material >= materials) fail("{}: triangle {} uses material {} of {}", label, i, t.material, materials);
    if (flags) {
      const uint32_t f = r.u32("triangle flags");
      if (f & ~(kUnlit | kInGap | kWhole)) fail("{}: triangle {} has unknown flags {:#x}", label, i, f);
      t.unlit = (f & kUnlit) != 0;
      t.in_gap = (f & kInGap) != 0;
      t.whole = (f & kWhole) != 0;
    }
  }
  if (!emitter) fail("{}: scene has no emitter", label);
  scene.background = r.vec("background");
  if (!finite(scene.background) || scene.background.x < 0 || scene.background.y < 0 || scene.background.z < 0)
    fail("{}: background is not finite and non-negative", label);
  uint32_t has_camera = r.u32("camera flag");
  if (has_camera > 1) fail("{}: camera flag {}", label, has_camera);
  if (has_camera) {
    Camera c;
    c.eye = r.vec("camera");
    c.look_at = r.vec("camera");
    c.up = r.vec("camera");
    c.vfov_deg = r.f32("camera");
    if (!finite(c.eye) || !finite(c.look_at) || !finite(c.up) || !(c.vfov_deg > 0.0f && c.vfov_deg < 180.0f))
      fail("{}: camera values out of range", label);
    scene.camera = c;
  }
  if (!r.done()) fail("{}: {} bytes after the scene", label, bytes.size() - kTag.size() - r.at());
  return scene;
}

std::string scene_bytes_hash(std::string_view bytes) {
  const XXH128_hash_t h = XXH3_128bits(bytes.data(), bytes.size());
  return fmt::format("{:016x}{:016x}", h.high64, h.low64);
}

bool is_scene_hash(std::string_view s) {
  return s.size() == 32 && s.find_first_not_of("0123456789abcdef") == std::string_view::npos;
}

}  // namespace sirad
