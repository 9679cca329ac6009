// sirad: rays traced as streams, and which patches share a place with another facing the same
// way (see rays.h).
#include "scene/rays.h"

#include "util/parallel.h"

namespace sirad {

namespace {

// Candidates looked at per patch at most: a patch whose neighbourhood holds more (slivers
// spanning the scene, a hostile mesh) is taken as overlapped, which is always right, only slower.
constexpr uint32_t kMaxCandidates = 4096;

// Faces closer than this to parallel (cosine of about 2.6 degrees) can share a place over an
// area; others meet within the tie only along a band about their crossing line.
constexpr double kParallel = 0.999;

struct Triangle {
  glm::dvec3 v[3];
  glm::dvec3 n;
};

Triangle triangle(const PatchMesh& mesh, uint32_t j) {
  const auto& p = mesh.patches[j];
  return {{glm::dvec3(mesh.vertices[p[0]]), glm::dvec3(mesh.vertices[p[1]]), glm::dvec3(mesh.vertices[p[2]])},
          glm::dvec3(mesh.normal[j])};
}

// The farthest of `b`'s corners from `a`'s plane.
double off_plane(const Triangle& a, const Triangle& b) {
  double d = 0.0;
  for (const glm::dvec3& v : b.v) d = std::max(d, std::abs(glm::dot(v - a.v[0], a.n)));
  return d;
}

// Whether triangles a and b, facing the same way, are one place over an area: nearly parallel,
// the corners of one within a few ties of the other's plane, and their shapes in a's plane
// overlapping by more than the tie along every separating axis (edges shared or touching
// overlap by nothing).
bool share_area(const Triangle& a, const Triangle& b, double tie) {
  if (glm::dot(a.n, b.n) < kParallel) return false;
  if (std::min(off_plane(a, b), off_plane(b, a)) > 4.0 * tie) return false;
  const glm::dvec3 u = glm::normalize(a.v[1] - a.v[0]), w = glm::cross(a.n, u);
  std::array<std::array<double, 2>, 3> pa, pb;
  for (int c = 0; c < 3; ++c) {
    pa[c] = {glm::dot(a.v[c] - a.v[0], u), glm::dot(a.v[c] - a.v[0], w)};
    pb[c] = {glm::dot(b.v[c] - a.v[0], u), glm::dot(b.v[c] - a.v[0], w)};
  }
  for (const auto* t : {&pa, &pb})
    for (int e = 0; e < 3; ++e) {
      const auto& p = (*t)[e];
      const auto& q = (*t)[(e + 1) % 3];
      double ax = q[1] - p[1], ay = p[0] - q[0];  // the edge's normal
      const double len = std::hypot(ax, ay);
      if (!(len > 0.0)) continue;
      ax /= len, ay /= len;
      double a0 = INFINITY, a1 = -INFINITY, b0 = INFINITY, b1 = -INFINITY;
      for (int c = 0; c < 3; ++c) {
        const double x = pa[c][0] * ax + pa[c][1] * ay, y = pb[c][0] * ax + pb[c][1] * ay;
        a0 = std::min(a0, x), a1 = std::max(a1, x), b0 = std::min(b0, y), b1 = std::max(b1, y);
      }
      if (std::min(a1, b1) - std::max(a0, b0) <= tie) return false;  // apart, or touching along a line
    }
  return true;
}

struct Query {
  const PatchMesh* mesh;
  Triangle self;
  uint32_t j;
  double tie;
  uint32_t looked = 0;
  bool found = false;
};

bool candidate(RTCPointQueryFunctionArguments* args) {
  auto* q = static_cast<Query*>(args->userPtr);
  const uint32_t k = args->primID;
  if (q->found || k == q->j) return false;
  if (++q->looked > kMaxCandidates || share_area(q->self, triangle(*q->mesh, k), q->tie)) {
    q->found = true;
    args->query->radius = 0.0f;  // nothing more to look for
    return true;
  }
  return false;
}

}  // namespace

void RayScene::seen_at(const glm::dvec3& org, const glm::dvec3* dir, std::size_t n, std::pair<int64_t, double>* out) const {
  thread_local std::vector<RTCRayHit> rh;
  rh.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    set_ray(rh[i].ray, org, dir[i], 0.0f, std::numeric_limits<float>::infinity());
    rh[i].hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh[i].hit.primID = RTC_INVALID_GEOMETRY_ID;
  }
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  rtcIntersect1M(scene_, &ctx, rh.data(), static_cast<unsigned>(n), sizeof(RTCRayHit));
  for (std::size_t i = 0; i < n; ++i) {
    if (rh[i].hit.geomID == RTC_INVALID_GEOMETRY_ID) {
      out[i] = {-1, std::numeric_limits<double>::infinity()};
      continue;
    }
    const double t = rh[i].ray.tfar;
    out[i] = {seen_from(org, dir[i], rh[i].hit.primID, t), t};
  }
}

void RayScene::blocked(const glm::dvec3* org, const glm::dvec3* to, std::size_t n, bool* out) const {
  thread_local std::vector<RTCRay> rays;
  rays.resize(n);
  for (std::size_t i = 0; i < n; ++i) set_ray(rays[i], org[i], to[i] - org[i], 0.0f, 1.0f);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  rtcOccluded1M(scene_, &ctx, rays.data(), static_cast<unsigned>(n), sizeof(RTCRay));
  for (std::size_t i = 0; i < n; ++i) out[i] = rays[i].tfar < 0.0f;
}

std::vector<uint8_t> RayScene::find_overlaps() const {
  const uint32_t n = static_cast<uint32_t>(mesh_.size());
  std::vector<uint8_t> out(n, 0);
  // A thread for every 4,096 faces, up to every core (a small mesh is not worth one).
  const unsigned threads = std::min(worker_threads(0), n / 4096 + 1);
  parallel_for(n, 1024, threads, [&](std::size_t begin, std::size_t end, unsigned) {
    for (uint32_t j = static_cast<uint32_t>(begin); j < end; ++j) {
      Query q{&mesh_, triangle(mesh_, j), j, tie_};
      const glm::dvec3 c = (q.self.v[0] + q.self.v[1] + q.self.v[2]) / 3.0;
      double r = 0.0;
      for (const glm::dvec3& v : q.self.v) r = std::max(r, glm::length(v - c));
      RTCPointQuery pq;
      pq.x = static_cast<float>(c.x), pq.y = static_cast<float>(c.y), pq.z = static_cast<float>(c.z);
      pq.time = 0.0f;
      pq.radius = static_cast<float>(r + 2.0 * tie_);
      RTCPointQueryContext ctx;
      rtcInitPointQueryContext(&ctx);
      rtcPointQuery(scene_, &pq, &ctx, &candidate, &q);
      out[j] = q.found ? 1 : 0;
    }
  });
  return out;
}

}  // namespace sirad
