// sirad: two-sided materials as one-sided faces (DESIGN.md section 1, "Two-sided surfaces"): each
// triangle of a two-sided material gets a reversed twin, kept only where that side can exchange
// light.
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include <glm/geometric.hpp>

#include "scene/import.h"
#include "scene/light_walks.h"
#include "scene/mesh.h"
#include "scene/rays.h"
#include "scene/scene.h"
#include "util/error.h"

namespace sirad {

void add_back_faces(Scene& scene) {
  // Every twin, then every original: where a twin and an original face the same way at one place
  // (the twin of one side of a zero-thickness wall on the other side's own face), the original
  // is the later patch, so it is on top (DESIGN.md, "Coincident faces").
  std::vector<Triangle> all;
  for (const Triangle& t : scene.triangles) {
    if (!scene.materials[t.material].two_sided) continue;
    Triangle back = t;
    back.back = true;
    std::swap(back.p[1], back.p[2]);
    all.push_back(back);
  }
  const std::size_t twins = all.size();
  if (twins == 0) return;
  if (twins + scene.triangles.size() > import::kMaxTriangles)
    fail("{}: more than {} triangles with the back faces of two-sided materials", scene.name, import::kMaxTriangles);
  all.insert(all.end(), scene.triangles.begin(), scene.triangles.end());
  scene.triangles = std::move(all);

  // A twin takes part where its side can receive light (scene/light_walks.h): a random walk from
  // it meets an emitter's front or sees one; an emitter's twin, where it lights some front. The
  // inside of a wall, slab or furniture box (and the floor under the bed, seen from inside it)
  // never leads out, and a sky plane's back faces nothing: no twin; the inside of a room made
  // from a cube with its normals out meets its lamp, or, through a door, another room's. A
  // closed box that emits inside (a box lamp) keeps its inner twins: they light each other.
  // Walks from under an original at the twin's place (the twin of one plane of a zero-thickness
  // wall lies under the other plane) count for nothing.
  const PatchMesh mesh = mesh_scene(scene, MeshOptions{});
  if (mesh.size() != scene.triangles.size()) return;  // a triangle the mesher drops: every twin kept
  const RayScene rays(mesh, ray_offset(mesh), /*fast=*/true);
  const std::vector<uint8_t> lit = light_reaches(mesh, rays, 0, twins, kWalkBudget);
  std::size_t kept = 0;  // the lit twins, in order, then every original
  for (std::size_t i = 0; i < twins; ++i)
    if (lit[i]) scene.triangles[kept++] = scene.triangles[i];
  scene.triangles.erase(scene.triangles.begin() + static_cast<std::ptrdiff_t>(kept),
                        scene.triangles.begin() + static_cast<std::ptrdiff_t>(twins));
}

}  // namespace sirad
