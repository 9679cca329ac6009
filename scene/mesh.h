// sirad: meshing a scene into patches, the unit of the radiosity solution.
// Each input triangle is split regularly into n x n sub-triangles (n from the longest edge, or
// for a sliver from its area, and the maximum edge length; a face no light reaches,
// Triangle::unlit, and a strip along a gap, Triangle::whole, stay one patch and count as one
// towards a target); a sub-triangle that the foot of another face crosses (a wall standing
// on a floor, scene/contacts.h) is split along it, so that no patch straddles a contact, and
// what lies inside the solid standing there is left out; vertices are welded so that shared corners carry one value
// (Gouraud shading, PLY connectivity). Patch order is stable: input triangle order, then
// sub-triangle order. The content hash names the meshed scene across processes.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "scene/scene.h"

namespace sirad {

struct MeshOptions {
  // At most one of these is set; both zero means one patch per input triangle, none split at
  // contacts (the meshes of add_back_faces and mark_unlit_faces, scene/scene.h).
  std::size_t target_patches = 0;  // subdivide to the patch count closest to this
  double max_edge = 0.0;           // subdivide until no patch edge is longer than this (a sliver: by its area, mesh.cpp)
  // Refuse a meshing to more patches than this (0: 2^31 - 1): a grid of more than 4 times it
  // before allocating, a meshing as soon as it passes 4 times it (the splits at contacts add
  // patches, the cover leaves some out, and a target's grid is then redone: mesh.cpp
  // kSplitHeadroom), and the final mesh beyond it. A node meshing a coordinator's scene takes no
  // more than the run says it has.
  uint64_t max_patches = 0;
};

struct PatchMesh {
  std::vector<glm::vec3> vertices;                // welded positions
  std::vector<std::array<uint32_t, 3>> patches;   // vertex indices, CCW seen from the front
  std::vector<glm::vec3> normal;                  // unit normal per patch
  std::vector<float> area;                        // per patch, > 0
  std::vector<uint32_t> material;                 // per patch, index into materials
  std::vector<uint32_t> source_triangle;          // per patch, index of the input triangle
  // Per patch, whether its triangle lies over an emitter across a gap (Triangle::in_gap); empty
  // when none does. Not in the content hash: only outputs depend on it (corner_radiosity).
  std::vector<uint8_t> in_gap;
  std::vector<uint32_t> triangle_object;          // per input triangle, index into objects
  std::vector<std::string> objects;               // object names (Scene::objects), for outputs
  std::vector<Material> materials;
  glm::vec3 background{0.0f};
  std::optional<Camera> camera;
  glm::vec3 bound_center{0.0f};                   // bounding sphere of all vertices
  float bound_radius = 0.0f;
  std::string hash;                               // 32 hex digits, XXH3-128 of the content

  std::size_t size() const { return patches.size(); }
  glm::vec3 reflectance(std::size_t j) const { return materials[material[j]].reflectance; }
  glm::vec3 emission(std::size_t j) const { return materials[material[j]].emission; }
  // Whether patch j emits (any channel above zero): the patches error measures leave out.
  bool emits(std::size_t j) const { return materials[material[j]].emits(); }
};

// Meshes `scene`. Throws sirad::Error on nonsensical options (negative, NaN, both set, a
// target so large it cannot be met with fewer than 2^31 patches).
PatchMesh mesh_scene(const Scene& scene, const MeshOptions& options);

// The content hash over the canonical bytes of the mesh (vertices, patches, materials,
// background). Recomputed by mesh_scene; exposed for tests and for nodes receiving a mesh.
std::string content_hash(const PatchMesh& mesh);

}  // namespace sirad
