// sirad: two-sided materials as one-sided faces (DESIGN.md section 1, "Two-sided surfaces"): each
// triangle of a two-sided material gets a reversed twin, kept only where that side can exchange
// light.
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include <glm/geometric.hpp>

#include "core/error.h"
#include "core/mesh.h"
#include "core/rays.h"
#include "core/scene.h"
#include "core/scene_import.h"

namespace sirad {
namespace {

// Random walks from all twins together, from each at least and at most, and their bounces.
constexpr std::size_t kWalkBudget = std::size_t{1} << 18;
constexpr int kMinWalks = 8, kMaxWalks = 64, kWalkBounces = 8;

}  // namespace

void add_back_faces(Scene& scene) {
  // Every twin, then every original: where a twin and an original face the same way at one place
  // (the twin of one side of a zero-thickness wall on the other side's own face), the original
  // is the later patch, so it is on top (DESIGN.md, "Coincident faces").
  std::vector<Triangle> all;
  for (const Triangle& t : scene.triangles) {
    if (!scene.materials[t.material].two_sided) continue;
    Triangle back = t;
    std::swap(back.p[1], back.p[2]);
    all.push_back(back);
  }
  const std::size_t twins = all.size();
  if (twins == 0) return;
  if (twins + scene.triangles.size() > import::kMaxTriangles)
    fail("{}: more than {} triangles with the back faces of two-sided materials", scene.name, import::kMaxTriangles);
  all.insert(all.end(), scene.triangles.begin(), scene.triangles.end());
  scene.triangles = std::move(all);

  // A twin takes part where its side can receive light: one of up to kMaxWalks cosine random
  // walks from it (kWalkBounces bounces each, over fronts only; a back or nothing ends a walk)
  // meets an emitter's front; an emitter's twin, where it lights some front. The inside of a
  // wall, slab or furniture box (and the floor under the bed, seen from inside it) never leads
  // out, and a sky plane's back faces nothing: no twin; the inside of a room made from a cube
  // with its normals out meets its lamp, or, through a door, another room's.
  // A closed box that emits inside (a box lamp) keeps its inner twins: they light each other.
  // Walks from under an original at the twin's place (the twin of one plane of a zero-thickness
  // wall lies under the other plane) count for nothing.
  const PatchMesh mesh = mesh_scene(scene, MeshOptions{});
  if (mesh.size() != scene.triangles.size()) return;  // a triangle the mesher drops: every twin kept
  const double eps = ray_offset(mesh);
  const RayScene rays(mesh, eps, /*fast=*/true);
  const int walks = static_cast<int>(std::clamp<std::size_t>(kWalkBudget / twins, kMinWalks, kMaxWalks));
  std::vector<std::array<double, 2>> pts, dirs;
  std::vector<uint8_t> lit(twins, 0);
  for (std::size_t i = 0; i < twins; ++i) {
    const auto& tri = mesh.patches[i];
    const glm::dvec3 a(mesh.vertices[tri[0]]), b(mesh.vertices[tri[1]]), c(mesh.vertices[tri[2]]);
    const bool emitter = mesh.emits(i);
    Rng rng(0x7317, i, 0, 6);
    stratified_square(walks, rng, pts);
    stratified_square(walks, rng, dirs);
    for (int k = 0; k < walks && !lit[i]; ++k) {
      const auto s = static_cast<std::size_t>(k);
      glm::dvec3 x = on_triangle(a, b, c, pts[s][0], pts[s][1]);
      if (rays.covered(static_cast<uint32_t>(i), x)) continue;
      glm::dvec3 n(mesh.normal[i]);
      glm::dvec3 d = cosine_direction(n, dirs[s][0], dirs[s][1]);
      for (int bounce = 0; bounce < kWalkBounces; ++bounce) {
        const auto [seen, t] = rays.seen_at(x + n * eps, d);
        if (seen < 0) break;
        const auto j = static_cast<std::size_t>(seen);
        n = glm::dvec3(mesh.normal[j]);
        if (!(glm::dot(n, d) < 0.0)) break;  // a back: no light from it
        if (mesh.emits(j) || emitter) {  // an emitter's twin counts if it lights some front
          lit[i] = 1;
          break;
        }
        x += d * t;
        d = cosine_direction(n, rng.uniform(), rng.uniform());
      }
    }
  }
  std::size_t kept = 0;  // the lit twins, in order, then every original
  for (std::size_t i = 0; i < twins; ++i)
    if (lit[i]) scene.triangles[kept++] = scene.triangles[i];
  scene.triangles.erase(scene.triangles.begin() + static_cast<std::ptrdiff_t>(kept),
                        scene.triangles.begin() + static_cast<std::ptrdiff_t>(twins));
}

}  // namespace sirad
