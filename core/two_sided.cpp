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

// Random walks from all twins together, from each at least and at most, and their bounces.
constexpr std::size_t kWalkBudget = std::size_t{1} << 18;
constexpr int kMinWalks = 8, kMaxWalks = 64, kWalkBounces = 8;

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

  // A twin takes part where its side can receive light: one of up to kMaxWalks cosine random
  // walks from it (kWalkBounces bounces each, over fronts only; a back or nothing ends a walk)
  // meets an emitter's front; an emitter's twin, where it lights some front. The inside of a
  // wall, slab or furniture box (and the floor under the bed, seen from inside it) never leads
  // out, and a sky plane's back faces nothing: no twin; the inside of a room made from a cube
  // with its normals out meets its lamp, or, through a door, another room's.
  // A closed box that emits inside (a box lamp) keeps its inner twins: they light each other.
  // Walks from under an original at the twin's place (the twin of one plane of a zero-thickness
  // wall lies under the other plane) count for nothing.
  const PatchMesh mesh = mesh_scene(all, MeshOptions{});
  if (mesh.size() != all.triangles.size()) {  // a triangle the mesher drops: every twin kept
    scene.triangles = std::move(all.triangles);
    return;
  }
  const RayScene rays(mesh, ray_offset(mesh), /*fast=*/true);
  const double eps = ray_offset(mesh);
  const int walks = static_cast<int>(std::clamp<std::size_t>(kWalkBudget / twins.size(), kMinWalks, kMaxWalks));
  std::vector<std::array<double, 2>> pts, dirs;
  std::vector<uint8_t> lit(twins.size(), 0);
  for (std::size_t i = 0; i < twins.size(); ++i) {
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
  std::vector<Triangle> out;
  out.reserve(all.triangles.size());
  for (std::size_t i = 0; i < twins.size(); ++i)
    if (lit[i]) out.push_back(twins[i]);
  out.insert(out.end(), scene.triangles.begin(), scene.triangles.end());
  scene.triangles = std::move(out);
}

}  // namespace sirad
