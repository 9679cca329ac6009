// sirad: two-sided materials as one-sided faces (DESIGN.md section 1, "Two-sided surfaces"): each
// triangle of a two-sided material gets a reversed twin, kept only where that side can exchange
// light.
#include <array>
#include <cstdint>
#include <vector>

#include <glm/geometric.hpp>

#include "core/error.h"
#include "core/mesh.h"
#include "core/rays.h"
#include "core/resources.h"
#include "core/scene.h"
#include "core/scene_import.h"

namespace sirad {
namespace {

// Rays cast from all twins together, and from each at least and at most.
constexpr std::size_t kTwinRayBudget = std::size_t{1} << 20;
constexpr int kMinTwinRays = 8, kMaxTwinRays = 32;

}  // namespace

void add_back_faces(Scene& scene) {
  std::vector<Triangle> twins;
  for (const Triangle& t : scene.triangles) {
    if (!scene.materials[t.material].two_sided) continue;
    Triangle back = t;
    std::swap(back.p[1], back.p[2]);
    twins.push_back(back);
  }
  if (twins.empty()) return;
  if (twins.size() + scene.triangles.size() > import::kMaxTriangles)
    fail("{}: more than {} triangles with the back faces of two-sided materials", scene.name, import::kMaxTriangles);

  // Every twin, then every original: where a twin and an original face the same way at one place
  // (the twin of one side of a zero-thickness wall on the other side's own face), the original
  // is the later patch, so it is on top (DESIGN.md, "Coincident faces").
  Scene all = scene;
  all.triangles = twins;
  all.triangles.insert(all.triangles.end(), scene.triangles.begin(), scene.triangles.end());

  // A twin takes part where its side sees light: one of its cosine rays meets the front of an
  // original face or of an emitter, or of a twin that does (found by a flood over the twins seen).
  // The back of a wall box (inside the solid) sees only other such twins and is dropped, as is
  // one that faces out into nothing (a sky plane's back); the inside of a room made from a cube
  // with its normals out sees its lamp and furniture, or walls that see them, and is kept. So is
  // none of a twin covered everywhere by an original at its place.
  const PatchMesh mesh = mesh_scene(all, MeshOptions{});
  if (mesh.size() != all.triangles.size()) fail("{}: two-sided faces: the mesh does not keep one patch per triangle", scene.name);
  const RayScene rays(mesh, ray_offset(mesh), /*fast=*/true);
  const double eps = ray_offset(mesh);
  const int per_twin = static_cast<int>(std::clamp<std::size_t>(kTwinRayBudget / twins.size(), kMinTwinRays, kMaxTwinRays));
  std::vector<std::array<double, 2>> pts, dirs;
  std::vector<uint8_t> lit(twins.size(), 0);
  std::vector<std::vector<uint32_t>> seen_by(twins.size());  // twin -> the twins that see its front
  for (std::size_t i = 0; i < twins.size(); ++i) {
    const auto& tri = mesh.patches[i];
    const glm::dvec3 a(mesh.vertices[tri[0]]), b(mesh.vertices[tri[1]]), c(mesh.vertices[tri[2]]), n(mesh.normal[i]);
    Rng rng(0x7317, i, 0, 6);
    stratified_square(per_twin, rng, pts);
    stratified_square(per_twin, rng, dirs);
    for (int k = 0; k < per_twin && !lit[i]; ++k) {
      const auto s = static_cast<std::size_t>(k);
      const glm::dvec3 x = on_triangle(a, b, c, pts[s][0], pts[s][1]);
      if (rays.covered(static_cast<uint32_t>(i), x)) continue;
      const glm::dvec3 d = cosine_direction(n, dirs[s][0], dirs[s][1]);
      const int64_t seen = rays.seen(x + n * eps, d);
      if (seen < 0) continue;
      const auto j = static_cast<std::size_t>(seen);
      if (!(glm::dot(glm::dvec3(mesh.normal[j]), d) < 0.0)) continue;  // a back: no light from it
      if (j >= twins.size() || mesh.emits(j)) {
        lit[i] = 1;
      } else if (j != i && (seen_by[j].empty() || seen_by[j].back() != i)) {
        seen_by[j].push_back(static_cast<uint32_t>(i));
      }
    }
  }
  std::vector<uint32_t> queue;
  for (std::size_t i = 0; i < twins.size(); ++i)
    if (lit[i]) queue.push_back(static_cast<uint32_t>(i));
  while (!queue.empty()) {
    const uint32_t j = queue.back();
    queue.pop_back();
    for (uint32_t i : seen_by[j])
      if (!lit[i]) {
        lit[i] = 1;
        queue.push_back(i);
      }
  }
  std::vector<Triangle> out;
  out.reserve(all.triangles.size());
  for (std::size_t i = 0; i < twins.size(); ++i)
    if (lit[i]) out.push_back(twins[i]);
  out.insert(out.end(), scene.triangles.begin(), scene.triangles.end());
  scene.triangles = std::move(out);
}

}  // namespace sirad
