// sirad: ray casting and sampling shared by the reference solver (solver/reference.h), the final
// gather (render/gather.h) and the scene checks (scene/check.h): a counter-keyed random stream, stratified points,
// cosine-distributed directions, and an Embree 3 scene of a mesh's patches that applies the
// coincident-face rule of DESIGN.md section 1.
#pragma once
#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "scene/mesh.h"
#include "util/error.h"

namespace sirad {


// splitmix64 as a stream: passes BigCrush, tiny state, keyed per (seed, patch, batch, purpose)
// so results do not depend on the thread count.
struct Rng {
  uint64_t s;
  static uint64_t mix(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  Rng(uint64_t seed, uint64_t a, uint64_t b, uint64_t c)
      : s(mix(mix(mix(seed ^ 0x5eed5eed5eedULL) ^ a) + b * 0x9e3779b97f4a7c15ULL) ^ (c << 56)) {}
  uint64_t next() { return mix(s += 0x9e3779b97f4a7c15ULL); }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }  // [0, 1)
};

// n stratified points in the unit square: an m x m jittered grid (m = floor(sqrt n)), the rest
// uniform, in random order (so that pairing two such sets is a random permutation).
inline void stratified_square(int n, Rng& rng, std::vector<std::array<double, 2>>& out) {
  out.resize(static_cast<std::size_t>(n));
  int m = static_cast<int>(std::sqrt(static_cast<double>(n)));
  while ((m + 1) * (m + 1) <= n) ++m;
  int k = 0;
  for (int a = 0; a < m; ++a)
    for (int b = 0; b < m; ++b) out[static_cast<std::size_t>(k++)] = {(a + rng.uniform()) / m, (b + rng.uniform()) / m};
  for (; k < n; ++k) out[static_cast<std::size_t>(k)] = {rng.uniform(), rng.uniform()};
  for (int i = n - 1; i > 0; --i) std::swap(out[static_cast<std::size_t>(i)], out[rng.next() % static_cast<uint64_t>(i + 1)]);
}

// Area-preserving map of the unit square onto the triangle (continuous, so strata stay strata).
inline glm::dvec3 on_triangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, double s, double t) {
  double r = std::sqrt(s);
  return a * (1.0 - r) + b * (r * (1.0 - t)) + c * (r * t);
}

// Cosine-distributed direction about n (Malley: concentric disk, lifted to the hemisphere).
inline glm::dvec3 cosine_direction(const glm::dvec3& n, double s, double t) {
  double a = 2.0 * s - 1.0, b = 2.0 * t - 1.0, r, phi;
  if (a == 0.0 && b == 0.0) {
    r = 0.0;
    phi = 0.0;
  } else if (std::abs(a) > std::abs(b)) {
    r = a;
    phi = (std::numbers::pi / 4.0) * (b / a);
  } else {
    r = b;
    phi = (std::numbers::pi / 2.0) - (std::numbers::pi / 4.0) * (a / b);
  }
  double x = r * std::cos(phi), y = r * std::sin(phi), z = std::sqrt(std::max(0.0, 1.0 - x * x - y * y));
  // Duff et al., "Building an orthonormal basis, revisited".
  double sign = std::copysign(1.0, n.z), e = -1.0 / (sign + n.z), f = n.x * n.y * e;
  glm::dvec3 u(1.0 + sign * n.x * n.x * e, sign * f, -sign * n.x), v(f, sign + n.y * n.y * e, -n.y);
  return u * x + v * y + n * z;
}

// How far a ray's origin leaves its surface, and how close faces are to count as one place: a
// few hundred float ulps of the scene's coordinates (1e-5 of their magnitude), at least the
// bundles' depth tie, far below any patch size or any gap a scene means to let light through.
inline double ray_offset(const PatchMesh& mesh) {
  return 1e-5 * (static_cast<double>(mesh.bound_radius) + glm::length(glm::dvec3(mesh.bound_center)));
}

// Embree scene of all patches (one triangle geometry, primID = patch index), robust mode so
// that rays do not slip between adjacent triangles.
//
// Coincident faces follow the rule of the bundles (DESIGN.md section 1, "Coincident faces"):
// surfaces closer than `tie` along a ray are one place; there a face that shows the ray its front
// is seen before any that shows its back (the two sides of a thin wall), and of faces that face
// the same way the later patch is on top (a rug laid on a floor at zero gap): the one below is
// covered and sees the back of the one on top.
//
// Only a face that shares a place with another facing the same way over an area (a rug on a
// floor, a duplicated face: `overlapped`, found once when the scene is built) needs that rule
// when it faces the ray: any other face within the tie of it meets it along a line (an edge, a
// contact, a thin wall's other side, which faces away), where either face is the place. There
// the first face met, facing the ray, is seen without a second look along the ray.
inline constexpr double kMaxRayReach = 1e15;

class RayScene {
 public:
  // `fast`: a quicker build of a slower tree, for a few rays (the scene checks); every hit then
  // takes the coincident-face rule's second look.
  RayScene(const PatchMesh& mesh, double tie, bool fast = false) : mesh_(mesh), tie_(tie) {
    // Embree takes ray origins within about 1.8e18 of the origin (it asserts, and aborts, past
    // that); a scene far beyond any real one is refused before a ray is cast.
    const double reach = static_cast<double>(mesh.bound_radius) + glm::length(glm::dvec3(mesh.bound_center));
    if (!(reach <= kMaxRayReach))
      fail("the scene reaches {:.3g} from the origin: too far to trace rays in (at most {:.0e})", reach, kMaxRayReach);
    device_ = rtcNewDevice(nullptr);
    if (!device_) fail("reference: cannot create an Embree device (error {})", static_cast<int>(rtcGetDeviceError(nullptr)));
    scene_ = rtcNewScene(device_);
    rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    rtcSetSceneBuildQuality(scene_, fast ? RTC_BUILD_QUALITY_LOW : RTC_BUILD_QUALITY_HIGH);
    RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                          3 * sizeof(float), mesh.vertices.size()));
    auto* ix = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                              3 * sizeof(unsigned), mesh.size()));
    if (!v || !ix) fail("reference: Embree could not allocate the scene buffers");
    for (std::size_t k = 0; k < mesh.vertices.size(); ++k)
      for (int c = 0; c < 3; ++c) v[3 * k + c] = mesh.vertices[k][c];
    for (std::size_t j = 0; j < mesh.size(); ++j)
      for (int c = 0; c < 3; ++c) ix[3 * j + c] = mesh.patches[j][c];
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene_, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scene_);
    if (rtcGetDeviceError(device_) != RTC_ERROR_NONE) fail("reference: Embree failed to build the scene");
    if (!fast) overlapped_ = find_overlaps();
  }
  ~RayScene() {
    rtcReleaseScene(scene_);
    rtcReleaseDevice(device_);
  }
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;

  // The patch a ray from org along dir meets first (t > 0), whichever side, or -1.
  int64_t nearest(const glm::dvec3& org, const glm::dvec3& dir) const { return first_hit(org, dir).first; }
  // The patch a ray from org along dir sees (t > 0): the front face it meets first, or -1 when
  // it meets a back face first or leaves the scene (it then brings the background).
  int64_t seen(const glm::dvec3& org, const glm::dvec3& dir) const { return seen_at(org, dir).first; }
  // seen(), with the distance (in units of |dir|) to the place it meets first (infinity: none).
  std::pair<int64_t, double> seen_at(const glm::dvec3& org, const glm::dvec3& dir) const {
    auto [first, t] = first_hit(org, dir);
    return {seen_from(org, dir, first, t), t};
  }
  // seen_at for n rays from one origin that go nearly one way (a camera's rays through one
  // pixel), traced together as a stream (Embree then traces them in packets): the same patches
  // and distances as n calls of seen_at.
  void seen_at(const glm::dvec3& org, const glm::dvec3* dir, std::size_t n, std::pair<int64_t, double>* out) const;
  // blocked for n segments (out[i]: whether org[i] to to[i] is), traced together as a stream.
  void blocked(const glm::dvec3* org, const glm::dvec3* to, std::size_t n, bool* out) const;
  // Whether patch j shares a place with another patch facing the same way over more than a line
  // (true for every patch of a `fast` scene: not looked for there).
  bool overlapped(uint32_t j) const { return overlapped_.empty() || overlapped_[j] != 0; }
  // Whether the point x of patch i has a face back to back with it at the same place (facing the
  // other way within the tie: a two-sided face's twin, the other plane of a zero-thickness wall).
  bool back_to_back(uint32_t i, const glm::dvec3& x) const {
    const glm::dvec3 n(mesh_.normal[i]);
    Hits h = hits_on(x - n * tie_, n, 0.0, 2.0 * tie_);
    for (uint32_t k = 0; k < h.n; ++k)
      if (h.prim[k] != i && glm::dot(glm::dvec3(mesh_.normal[h.prim[k]]), n) < -0.5) return true;
    return false;
  }
  // Whether the point x of patch i lies under a later patch at the same place facing the same
  // way (it then sees that patch's back, and no light reaches it).
  bool covered(uint32_t i, const glm::dvec3& x) const {
    const glm::dvec3 n(mesh_.normal[i]);
    // A neighbour on the same surface (sharing a vertex with patch i) meets the probe only at
    // their shared edge, and covers nothing: from it only a hit well inside counts.
    Hits h = hits_on(x - n * tie_, n, 0.0, 2.0 * tie_);
    const auto& own = mesh_.patches[i];
    for (uint32_t k = 0; k < h.n; ++k) {
      const uint32_t p = h.prim[k];
      if (p <= i || !(glm::dot(glm::dvec3(mesh_.normal[p]), n) > 0.0)) continue;
      bool neighbour = false;
      for (uint32_t v : mesh_.patches[p]) neighbour = neighbour || v == own[0] || v == own[1] || v == own[2];
      if (!neighbour || h.inside[k] >= 1e-5f) return true;
    }
    return false;
  }
  // The patch on top at place x among those facing the way n there (within the tie): the latest,
  // by the coincident-face rule (a rug laid on a floor); -1 where none faces n at x.
  int64_t on_top(const glm::dvec3& x, const glm::dvec3& n) const {
    Hits h = hits_on(x - n * tie_, n, 0.0, 2.0 * tie_);
    int64_t top = -1;
    for (uint32_t k = 0; k < h.n; ++k)
      if (glm::dot(glm::dvec3(mesh_.normal[h.prim[k]]), n) > 0.5) top = std::max<int64_t>(top, h.prim[k]);
    return top;
  }
  // Whether anything lies on the segment org + t (to - org), 0 <= t < 1.
  bool blocked(const glm::dvec3& org, const glm::dvec3& to) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRay r;
    set_ray(r, org, to - org, 0.0f, 1.0f);
    rtcOccluded1(scene_, &ctx, &r);
    return r.tfar < 0.0f;
  }

 private:
  // What a ray sees whose first hit is `first` at `t`: that face if it faces the ray and shares
  // no place; else, by the rule, the latest face within the tie of t that faces the ray (-1: none,
  // or no first hit).
  int64_t seen_from(const glm::dvec3& org, const glm::dvec3& dir, int64_t first, double t) const {
    if (first < 0) return -1;
    if (!overlapped(static_cast<uint32_t>(first)) && glm::dot(glm::dvec3(mesh_.normal[first]), dir) < 0.0) return first;
    Hits near = hits_on(org, dir, std::max(0.0, t - tie_), t + tie_);
    int64_t best = -1;
    for (uint32_t k = 0; k < near.n; ++k)
      if (glm::dot(glm::dvec3(mesh_.normal[near.prim[k]]), dir) < 0.0) best = std::max<int64_t>(best, near.prim[k]);
    return best;
  }
  // The nearest patch on org + t dir, t > 0, and its t (-1 and infinity: none).
  std::pair<int64_t, double> first_hit(const glm::dvec3& org, const glm::dvec3& dir) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh;
    set_ray(rh.ray, org, dir, 0.0f, std::numeric_limits<float>::infinity());
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return {-1, std::numeric_limits<double>::infinity()};
    return {static_cast<int64_t>(rh.hit.primID), static_cast<double>(rh.ray.tfar)};
  }
  // The patches met on org + t dir, t0 <= t <= t1 (the first 16, each once).
  struct Hits {
    RTCIntersectContext ctx;  // first: Embree hands the filter this address
    uint32_t n = 0;
    std::array<uint32_t, 16> prim{};
    std::array<float, 16> inside{};  // the least barycentric coordinate of the hit
  };
  static void collect(const RTCFilterFunctionNArguments* args) {
    auto* h = reinterpret_cast<Hits*>(args->context);
    for (unsigned r = 0; r < args->N; ++r) {
      if (args->valid[r] == 0) continue;
      uint32_t prim = RTCHitN_primID(args->hit, args->N, r);
      float u = RTCHitN_u(args->hit, args->N, r), v = RTCHitN_v(args->hit, args->N, r);
      if (h->n < h->prim.size() && std::find(h->prim.begin(), h->prim.begin() + h->n, prim) == h->prim.begin() + h->n) {
        h->inside[h->n] = std::min(std::min(u, v), 1.0f - u - v);
        h->prim[h->n++] = prim;
      }
      args->valid[r] = 0;  // refused: the traversal goes on to the next hit
    }
  }
  Hits hits_on(const glm::dvec3& org, const glm::dvec3& dir, double t0, double t1) const {
    Hits h;
    rtcInitIntersectContext(&h.ctx);
    h.ctx.filter = &RayScene::collect;
    RTCRayHit rh;
    set_ray(rh.ray, org, dir, static_cast<float>(t0), static_cast<float>(t1));
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene_, &h.ctx, &rh);
    return h;
  }
  static void set_ray(RTCRay& r, const glm::dvec3& org, const glm::dvec3& dir, float tnear, float tfar) {
    r.org_x = static_cast<float>(org.x);
    r.org_y = static_cast<float>(org.y);
    r.org_z = static_cast<float>(org.z);
    r.tnear = tnear;
    r.dir_x = static_cast<float>(dir.x);
    r.dir_y = static_cast<float>(dir.y);
    r.dir_z = static_cast<float>(dir.z);
    r.time = 0.0f;
    r.tfar = tfar;
    r.mask = 0xffffffffu;
    r.id = 0;
    r.flags = 0;
  }
  // overlapped() for every patch (scene/rays.cpp).
  std::vector<uint8_t> find_overlaps() const;
  const PatchMesh& mesh_;
  double tie_;
  RTCDevice device_;
  RTCScene scene_;
  std::vector<uint8_t> overlapped_;  // per patch; empty: not looked for
};

}  // namespace sirad
