// sirad: random walks that find which faces light can reach (see light_walks.h), and the faces no
// light reaches left whole (scene.h mark_unlit_faces).
#include "scene/light_walks.h"

#include <algorithm>
#include <array>
#include <bit>

#include <glm/geometric.hpp>

#include "scene/scene.h"

namespace sirad {

std::vector<uint8_t> light_reaches(const PatchMesh& mesh, const RayScene& rays, std::size_t first, std::size_t count,
                                   std::size_t budget) {
  std::vector<uint32_t> emitters;
  for (std::size_t j = 0; j < mesh.size(); ++j)
    if (mesh.emits(j)) emitters.push_back(static_cast<uint32_t>(j));
  const double eps = ray_offset(mesh);
  // Whether x (on a face of normal n) sees the front of a random point of emitting face e.
  auto sees = [&](const glm::dvec3& x, const glm::dvec3& n, uint32_t e, Rng& rng) {
    const auto& tri = mesh.patches[e];
    const glm::dvec3 y = on_triangle(glm::dvec3(mesh.vertices[tri[0]]), glm::dvec3(mesh.vertices[tri[1]]),
                                     glm::dvec3(mesh.vertices[tri[2]]), rng.uniform(), rng.uniform());
    const glm::dvec3 ne(mesh.normal[e]);
    return glm::dot(n, y - x) > 0.0 && glm::dot(ne, x - y) > 0.0 && !rays.blocked(x + n * eps, y + ne * eps);
  };
  auto any_emitter = [&](Rng& rng) {
    return emitters[std::min<std::size_t>(emitters.size() - 1, static_cast<std::size_t>(rng.uniform() * emitters.size()))];
  };
  // From a walk's start, a point on each emitting face (kLightsTried of them at random where
  // there are more): a face that sees a light, however little of it (a wall beside a sky plane
  // that sees its edge), is found by its first walks; from a bounce, one emitting face at random.
  auto sees_a_light = [&](const glm::dvec3& x, const glm::dvec3& n, Rng& rng, bool start) {
    if (emitters.empty()) return false;
    if (!start) return sees(x, n, any_emitter(rng), rng);
    if (emitters.size() <= kLightsTried) {
      for (uint32_t e : emitters)
        if (sees(x, n, e, rng)) return true;
      return false;
    }
    for (std::size_t k = 0; k < kLightsTried; ++k)
      if (sees(x, n, any_emitter(rng), rng)) return true;
    return false;
  };
  const int walks = static_cast<int>(std::clamp<std::size_t>(budget / std::max<std::size_t>(count, 1), kMinWalks, kMaxWalks));
  std::vector<std::array<double, 2>> pts, dirs;
  std::vector<uint8_t> lit(count, 0);
  for (std::size_t f = 0; f < count; ++f) {
    const std::size_t i = first + f;
    const auto& tri = mesh.patches[i];
    const glm::dvec3 a(mesh.vertices[tri[0]]), b(mesh.vertices[tri[1]]), c(mesh.vertices[tri[2]]);
    const bool emitter = mesh.emits(i);
    // Keyed by the face's corners, not its index: a face's walks, and so whether it is marked,
    // do not change when faces elsewhere are cut or added.
    uint64_t key = 0;
    for (uint32_t v : tri)
      for (int d = 0; d < 3; ++d) key = Rng::mix(key ^ std::bit_cast<uint32_t>(mesh.vertices[v][d]));
    Rng rng(0x7317, key, 0, 6);
    stratified_square(walks, rng, pts);
    stratified_square(walks, rng, dirs);
    for (int k = 0; k < walks && !lit[f]; ++k) {
      const auto s = static_cast<std::size_t>(k);
      glm::dvec3 x = on_triangle(a, b, c, pts[s][0], pts[s][1]);
      if (rays.covered(static_cast<uint32_t>(i), x)) continue;
      glm::dvec3 n(mesh.normal[i]);
      if (!emitter && sees_a_light(x, n, rng, true)) {
        lit[f] = 1;
        break;
      }
      glm::dvec3 d = cosine_direction(n, dirs[s][0], dirs[s][1]);
      for (int bounce = 0; bounce < kWalkBounces; ++bounce) {
        const auto [seen, t] = rays.seen_at(x + n * eps, d);
        if (seen < 0) break;
        const auto j = static_cast<std::size_t>(seen);
        n = glm::dvec3(mesh.normal[j]);
        if (!(glm::dot(n, d) < 0.0)) break;  // a back: no light from it
        x += d * t;
        if (mesh.emits(j) || emitter || sees_a_light(x, n, rng, false)) {  // an emitter's own face counts if it lights some front
          lit[f] = 1;
          break;
        }
        d = cosine_direction(n, rng.uniform(), rng.uniform());
      }
    }
  }
  return lit;
}

void mark_unlit_faces(Scene& scene) {
  // Each face takes at least kMinWalks walks of up to kLightsTried + 2 kWalkBounces rays: past
  // kMaxMarkedFaces faces the load would take minutes, and nothing is marked (only the patch
  // budget is then spent as before).
  if (scene.triangles.empty() || scene.triangles.size() > kMaxMarkedFaces) return;
  const PatchMesh mesh = mesh_scene(scene, MeshOptions{});
  if (mesh.size() != scene.triangles.size()) return;  // a triangle the mesher drops: none marked
  const RayScene rays(mesh, ray_offset(mesh), /*fast=*/true);
  const std::vector<uint8_t> lit = light_reaches(mesh, rays, 0, mesh.size(), kWalkBudget);
  for (std::size_t i = 0; i < scene.triangles.size(); ++i)
    scene.triangles[i].unlit = !lit[i] && !mesh.emits(i);
}

}  // namespace sirad
