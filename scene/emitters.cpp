// sirad: the emitters as the direct light samples them (see emitters.h).
#include "scene/emitters.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <unordered_map>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include "scene/rays.h"
#include "util/polygon.h"

namespace sirad {

namespace {

using glm::dvec3;

// Patches are one light's if they share a vertex, a material and a plane: normals within
// acos(kSameNormal), vertices within kSamePlane of the group's extent off its plane. A light's
// shape must match its patches' area to kSameArea.
constexpr double kSameNormal = 0.9999, kSamePlane = 1e-5, kSameArea = 1e-4;
// At most this many groups meet at one vertex (bounds the work of a hostile mesh whose faces all
// share a vertex: the patches past it are their own lights, which is only noisier).
constexpr std::size_t kGroupsAtAVertex = 8;

struct Groups {  // union-find
  std::vector<uint32_t> parent;
  uint32_t find(uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  void join(uint32_t a, uint32_t b) { parent[find(a)] = find(b); }
};

std::vector<uint32_t> emitting_patches(const PatchMesh& mesh) {
  std::vector<uint32_t> out;
  for (std::size_t j = 0; j < mesh.size(); ++j)
    if (mesh.emits(j)) out.push_back(static_cast<uint32_t>(j));
  return out;
}

Light patch_light(const PatchMesh& mesh, uint32_t j) {
  Light l;
  for (int k = 0; k < 3; ++k) l.p[static_cast<std::size_t>(k)] = dvec3(mesh.vertices[mesh.patches[j][static_cast<std::size_t>(k)]]);
  l.normal = dvec3(mesh.normal[j]);
  l.area = mesh.area[j];
  l.emission = dvec3(mesh.emission(j));
  return l;
}

// The triangle or parallelogram the patches `members` (one material, one plane of normal n)
// fill, if they do.
bool as_one_shape(const PatchMesh& mesh, const std::vector<uint32_t>& members, const dvec3& n, Light& out) {
  std::vector<uint32_t> vertices;
  double area = 0.0;
  for (uint32_t j : members) {
    vertices.insert(vertices.end(), mesh.patches[j].begin(), mesh.patches[j].end());
    area += mesh.area[j];
  }
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  std::vector<dvec3> pts;
  for (uint32_t v : vertices) pts.push_back(dvec3(mesh.vertices[v]));
  const dvec3 o(mesh.vertices[mesh.patches[members[0]][0]]);
  const dvec3 u = glm::normalize(dvec3(mesh.vertices[mesh.patches[members[0]][1]]) - o), w = glm::cross(n, u);  // (u, w, n) right-handed
  double extent = 0.0;
  for (const dvec3& p : pts) extent = std::max(extent, glm::length(p - o));
  if (!(extent > 0.0)) return false;
  for (const dvec3& p : pts)
    if (std::abs(glm::dot(n, p - o)) > kSamePlane * extent) return false;
  // The convex hull in the plane, counter-clockwise seen from the front; points on its edges
  // (within rounding) left out.
  std::vector<glm::dvec2> q(pts.size());
  for (std::size_t k = 0; k < pts.size(); ++k) q[k] = {glm::dot(pts[k] - o, u), glm::dot(pts[k] - o, w)};
  const std::vector<std::size_t> hull = convex_hull(q, 1e-7 * extent * extent);
  if (hull.size() != 3 && hull.size() != 4) return false;
  out.corners = static_cast<int>(hull.size());
  for (std::size_t i = 0; i < hull.size(); ++i) out.p[i] = pts[hull[i]];
  const dvec3 c = glm::cross(out.p[1] - out.p[0], out.p[hull.size() - 1] - out.p[0]);
  if (hull.size() == 4) {
    if (glm::length(out.p[0] + out.p[2] - out.p[1] - out.p[3]) > kSamePlane * extent) return false;
    out.area = glm::length(c);
  } else {
    out.area = 0.5 * glm::length(c);
  }
  if (!(out.area > 0.0) || std::abs(out.area - area) > kSameArea * area) return false;
  out.normal = c / glm::length(c);
  out.emission = dvec3(mesh.emission(members[0]));
  return glm::dot(out.normal, n) > kSameNormal;
}

// The input triangles of `members`, each rebuilt from its patches (the extreme points of their
// vertices: regular subdivision keeps the corners) where they fill it; else its patches.
void by_input_triangle(const PatchMesh& mesh, const std::vector<uint32_t>& members, std::vector<Light>& out,
                       std::vector<int32_t>* light_of = nullptr) {
  auto mark = [&](uint32_t j) {
    if (light_of) (*light_of)[j] = static_cast<int32_t>(out.size() - 1);
  };
  std::map<uint32_t, std::vector<uint32_t>> triangles;
  for (uint32_t j : members) triangles[j < mesh.source_triangle.size() ? mesh.source_triangle[j] : 0xffffffffu].push_back(j);
  for (const auto& [t, patches] : triangles) {
    std::vector<dvec3> pts;
    double area = 0.0;
    bool same = true;
    for (uint32_t j : patches) {
      for (uint32_t v : mesh.patches[j]) pts.push_back(dvec3(mesh.vertices[v]));
      area += mesh.area[j];
      same = same && mesh.material[j] == mesh.material[patches[0]];
    }
    dvec3 centre(0.0);
    for (const dvec3& q : pts) centre += q / static_cast<double>(pts.size());
    auto farthest = [&](const dvec3& from) {
      std::size_t best = 0;
      for (std::size_t k = 1; k < pts.size(); ++k)
        if (glm::length(pts[k] - from) > glm::length(pts[best] - from)) best = k;
      return pts[best];
    };
    dvec3 a = farthest(centre), b = farthest(a), c = a;
    double best = -1.0;
    for (const dvec3& q : pts) {
      const double s = glm::length(glm::cross(b - a, q - a));
      if (s > best) best = s, c = q;
    }
    Light l = patch_light(mesh, patches[0]);
    const dvec3 cr = glm::cross(b - a, c - a);
    const double tri_area = 0.5 * glm::length(cr);
    if (t == 0xffffffffu || !same || !(tri_area > 0.0) || std::abs(tri_area - area) > kSameArea * area ||
        std::abs(glm::dot(cr / (2.0 * tri_area), l.normal)) <= kSameNormal) {
      for (uint32_t j : patches) {
        out.push_back(patch_light(mesh, j));
        mark(j);
      }
      continue;
    }
    if (glm::dot(cr, l.normal) < 0.0) std::swap(b, c);
    l.p = {a, b, c, dvec3(0.0)};
    l.normal = glm::normalize(glm::cross(b - a, c - a));
    l.area = tri_area;
    out.push_back(l);
    for (uint32_t j : patches) mark(j);
  }
}

}  // namespace

dvec3 Light::at(double s, double t) const {
  if (corners == 4) return p[0] + s * (p[1] - p[0]) + t * (p[3] - p[0]);
  return on_triangle(p[0], p[1], p[2], s, t);
}

std::vector<Light> find_lights(const PatchMesh& mesh, std::vector<int32_t>* light_of) {
  if (light_of) light_of->assign(mesh.size(), -1);
  const std::vector<uint32_t> emitting = emitting_patches(mesh);
  Groups groups{std::vector<uint32_t>(emitting.size())};
  std::iota(groups.parent.begin(), groups.parent.end(), 0u);
  // Whether emitting patches a and b (indices into `emitting`) may be one light's.
  auto alike = [&](uint32_t a, uint32_t b) {
    const uint32_t ja = emitting[a], jb = emitting[b];
    if (mesh.material[ja] != mesh.material[jb]) return false;
    const dvec3 n(mesh.normal[ja]);
    if (glm::dot(n, dvec3(mesh.normal[jb])) <= kSameNormal) return false;
    const dvec3 o(mesh.vertices[mesh.patches[ja][0]]);
    double extent = 0.0;
    for (uint32_t v : mesh.patches[jb]) extent = std::max(extent, glm::length(dvec3(mesh.vertices[v]) - o));
    for (uint32_t v : mesh.patches[jb])
      if (std::abs(glm::dot(n, dvec3(mesh.vertices[v]) - o)) > kSamePlane * extent) return false;
    return true;
  };
  std::unordered_map<uint32_t, std::vector<uint32_t>> at_vertex;  // vertex -> one patch of each group there
  for (uint32_t a = 0; a < emitting.size(); ++a)
    for (uint32_t v : mesh.patches[emitting[a]]) {
      std::vector<uint32_t>& seen = at_vertex[v];
      bool joined = false;
      for (uint32_t b : seen)
        if (alike(a, b)) {
          groups.join(a, b);
          joined = true;
          break;
        }
      if (!joined && seen.size() < kGroupsAtAVertex) seen.push_back(a);
    }
  std::map<uint32_t, std::vector<uint32_t>> sets;  // by root; then in the order of their first patch
  for (uint32_t a = 0; a < emitting.size(); ++a) sets[groups.find(a)].push_back(emitting[a]);
  std::vector<std::vector<uint32_t>> ordered;
  for (auto& [root, members] : sets) ordered.push_back(std::move(members));
  std::sort(ordered.begin(), ordered.end(), [](const auto& a, const auto& b) { return a[0] < b[0]; });
  std::vector<Light> out;
  for (const std::vector<uint32_t>& members : ordered) {
    Light l;
    if (as_one_shape(mesh, members, dvec3(mesh.normal[members[0]]), l)) {
      out.push_back(l);
      if (light_of)
        for (uint32_t j : members) (*light_of)[j] = static_cast<int32_t>(out.size() - 1);
    } else {
      by_input_triangle(mesh, members, out, light_of);
    }
  }
  return out;
}

std::vector<Light> input_triangle_lights(const PatchMesh& mesh) {
  std::vector<Light> out;
  by_input_triangle(mesh, emitting_patches(mesh), out);
  return out;
}

}  // namespace sirad
