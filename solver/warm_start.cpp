// sirad: matching a new mesh's patches to a previous run's (see warm_start.h).
#include "solver/warm_start.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <unordered_map>

#include <glm/geometric.hpp>

#include "util/error.h"

namespace sirad {

namespace {

using Corner = std::array<int64_t, 3>;
using Key = std::array<Corner, 3>;

struct KeyHash {
  std::size_t operator()(const Key& k) const {
    std::size_t h = 1469598103934665603ull;
    for (const Corner& c : k)
      for (int64_t v : c) h = (h ^ static_cast<std::size_t>(v)) * 1099511628211ull;
    return h;
  }
};

// A patch's corners rounded to the grid `cell`, rotated to start at the least: the same key
// for the same triangle whatever corner it lists first, a different one for the other winding.
Key key_of(const PatchMesh& mesh, std::size_t j, double cell) {
  Key k;
  for (int c = 0; c < 3; ++c) {
    const glm::dvec3 v(mesh.vertices[mesh.patches[j][static_cast<std::size_t>(c)]]);
    for (int a = 0; a < 3; ++a) k[static_cast<std::size_t>(c)][static_cast<std::size_t>(a)] = std::llround(v[a] / cell);
  }
  std::rotate(k.begin(), std::min_element(k.begin(), k.end()), k.end());
  return k;
}

}  // namespace

std::vector<int64_t> match_patches(const PatchMesh& now, const PatchMesh& before, double tolerance) {
  if (!(tolerance > 0.0) || !std::isfinite(tolerance)) fail("match_patches: tolerance {} is not a positive number", tolerance);
  const double reach = std::max(static_cast<double>(now.bound_radius) + glm::length(glm::dvec3(now.bound_center)),
                                static_cast<double>(before.bound_radius) + glm::length(glm::dvec3(before.bound_center)));
  if (reach / tolerance > 1e15) fail("match_patches: tolerance {} too fine for a scene {} across", tolerance, reach);
  std::unordered_map<Key, int64_t, KeyHash> old;
  old.reserve(before.size());
  for (std::size_t i = 0; i < before.size(); ++i) old.emplace(key_of(before, i, tolerance), static_cast<int64_t>(i));
  std::vector<int64_t> match(now.size(), -1);
  for (std::size_t j = 0; j < now.size(); ++j) {
    const auto it = old.find(key_of(now, j, tolerance));
    if (it != old.end()) match[j] = it->second;
  }
  return match;
}

void share_bound(PatchMesh& a, PatchMesh& b) {
  const glm::dvec3 ca(a.bound_center), cb(b.bound_center);
  const double ra = a.bound_radius, rb = b.bound_radius, d = glm::length(cb - ca);
  glm::dvec3 c = ca;
  double r = ra;
  if (d + rb <= ra) {
    // b's sphere lies within a's
  } else if (d + ra <= rb) {
    c = cb, r = rb;
  } else {
    r = (d + ra + rb) / 2.0;
    c = ca + (cb - ca) * ((r - ra) / d);
  }
  // Widened past float rounding (of the radius and of the centre) so that the float sphere still
  // holds both.
  const double slack = 1e-6 * (r + glm::length(c));
  const float radius = std::nextafter(static_cast<float>(r + slack), std::numeric_limits<float>::infinity());
  a.bound_center = b.bound_center = glm::vec3(c);
  a.bound_radius = b.bound_radius = radius;
}

}  // namespace sirad
