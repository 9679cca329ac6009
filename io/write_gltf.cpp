// sirad: the solution as a binary glTF 2.0 file (io/write_gltf.h), written with tinygltf.
#include "io/write_gltf.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>

#include <fmt/format.h>
#include <glm/geometric.hpp>

#include "io/gltf_build.h"
#include "scene/rays.h"
#include "scene/scene.h"
#include "util/error.h"

namespace sirad {

namespace {

// Which patches have a face back to back with them at their centre (a two-sided face and its
// twin, the two planes of a zero-thickness wall, however each is cut into triangles).
std::vector<uint8_t> back_to_back(const PatchMesh& mesh) {
  std::vector<uint8_t> paired(mesh.size(), 0);
  if (mesh.size() == 0) return paired;
  const RayScene rays(mesh, ray_offset(mesh), /*fast=*/true);
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const auto& t = mesh.patches[j];
    const glm::dvec3 centre = (glm::dvec3(mesh.vertices[t[0]]) + glm::dvec3(mesh.vertices[t[1]]) + glm::dvec3(mesh.vertices[t[2]])) / 3.0;
    paired[j] = rays.back_to_back(static_cast<uint32_t>(j), centre);
  }
  return paired;
}

}  // namespace

void write_glb(const std::string& path, const PatchMesh& mesh, const std::vector<glm::vec3>& radiosity, float exposure,
               double aspect) {
  if (radiosity.size() != mesh.size()) fail("cannot write {}: {} radiosity values for {} patches", path, radiosity.size(), mesh.size());
  if (!std::isfinite(exposure)) fail("cannot write {}: exposure is not finite", path);
  const auto corners = corner_radiosity(mesh, radiosity);
  const float scale = std::exp2(exposure);
  tinygltf::Model m;
  m.asset.version = "2.0";
  m.asset.generator = "sirad";
  // sirad_exposure: the stops COLOR_0 is scaled by (and the PNG's); a viewer showing _RADIANCE
  // starts there.
  m.asset.extras = tinygltf::Value(tinygltf::Value::Object{{"sirad_background", gltf::triple(mesh.background)},
                                                           {"sirad_exposure", tinygltf::Value(static_cast<double>(exposure))}});
  m.extensionsUsed.push_back("KHR_materials_unlit");
  m.buffers.resize(1);
  for (const Material& mat : mesh.materials) {
    tinygltf::Material g;
    g.name = mat.name;
    g.pbrMetallicRoughness.baseColorFactor = {1.0, 1.0, 1.0, 1.0};  // the colour is the vertices'
    g.pbrMetallicRoughness.metallicFactor = 0.0;
    g.pbrMetallicRoughness.roughnessFactor = 1.0;
    g.extensions["KHR_materials_unlit"] = tinygltf::Value(tinygltf::Value::Object());
    g.extras = tinygltf::Value(tinygltf::Value::Object{{"sirad_reflectance", gltf::triple(mat.reflectance)},
                                                       {"sirad_emission", gltf::triple(mat.emission)}});
    m.materials.push_back(g);
  }
  // Patches by object, then by material: one mesh per object, one primitive per material.
  std::map<uint32_t, std::map<uint32_t, std::vector<uint32_t>>> parts;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    uint32_t object = mesh.source_triangle[j] < mesh.triangle_object.size() ? mesh.triangle_object[mesh.source_triangle[j]] : 0;
    parts[object][mesh.material[j]].push_back(static_cast<uint32_t>(j));
  }
  // Cycles ignores back-face culling: of two faces back to back at one place it shows either,
  // speckled. Each is pulled kSidesApart of the scene's radius along its own normal, so that
  // every viewer (Cycles, Eevee, three.js) meets the side that faces it first.
  const std::vector<uint8_t> paired = back_to_back(mesh);
  const double apart = kSidesApart * static_cast<double>(mesh.bound_radius);
  tinygltf::Scene scene;
  for (const auto& [object, by_material] : parts) {
    tinygltf::Mesh gm;
    gm.name = object < mesh.objects.size() ? mesh.objects[object] : fmt::format("object {}", object);
    for (const auto& [material, patches] : by_material) {
      // A vertex per welded position and corner value (split_corners).
      std::vector<uint32_t> welded;
      std::vector<glm::vec3> value;
      const std::vector<uint32_t> indices = split_corners(mesh, corners, patches, welded, value);
      std::vector<glm::dvec3> pull(welded.size(), glm::dvec3(0.0));  // summed normals of paired patches
      for (std::size_t k = 0; k < patches.size(); ++k)
        if (paired[patches[k]])
          for (int c = 0; c < 3; ++c) pull[indices[3 * k + static_cast<std::size_t>(c)]] += glm::dvec3(mesh.normal[patches[k]]);
      std::vector<float> position, colour, radiance;
      for (std::size_t v = 0; v < welded.size(); ++v)
        for (int a = 0; a < 3; ++a) {
          const double length = glm::length(pull[v]);
          position.push_back(static_cast<float>(static_cast<double>(mesh.vertices[welded[v]][a]) +
                                                (length > 0.0 ? apart * pull[v][a] / length : 0.0)));
          radiance.push_back(value[v][a]);
          colour.push_back(std::clamp(value[v][a] * scale, 0.0f, 1.0f));
        }
      tinygltf::Primitive prim;
      prim.mode = TINYGLTF_MODE_TRIANGLES;
      prim.material = static_cast<int>(material);
      prim.attributes["POSITION"] = gltf::add_positions(m, position);
      prim.attributes["COLOR_0"] = gltf::add_vec3(m, colour);
      prim.attributes["_RADIANCE"] = gltf::add_vec3(m, radiance);
      prim.indices = gltf::add_indices(m, indices);
      gm.primitives.push_back(prim);
    }
    gltf::add_mesh(m, scene, std::move(gm));
  }
  if (mesh.camera) gltf::add_camera(m, scene, *mesh.camera, mesh.bound_center, mesh.bound_radius, aspect);
  gltf::save_glb(m, std::move(scene), path);
}

}  // namespace sirad
