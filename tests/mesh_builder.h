// sirad tests: patch meshes made by hand (MeshBuilder), and two of them: a quad facing the
// camera and the inside of a cube whose faces have radiosities of their own.
#pragma once
#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "scene/mesh.h"
#include "scene/scene.h"

namespace sirad::test {

// Builds a PatchMesh by hand: normal and area from each patch's CCW winding.
struct MeshBuilder {
  PatchMesh mesh;

  MeshBuilder() {
    mesh.materials = {Material{"white", glm::vec3(0.5f, 0.6f, 0.7f), glm::vec3(0.0f)},
                      Material{"light", glm::vec3(0.25f), glm::vec3(10.0f, 20.0f, 30.0f)}};
    mesh.hash = "0123456789abcdef0123456789abcdef";
  }
  uint32_t vertex(glm::vec3 p) {
    mesh.vertices.push_back(p);
    return static_cast<uint32_t>(mesh.vertices.size() - 1);
  }
  void patch(uint32_t a, uint32_t b, uint32_t c, uint32_t material = 0) {
    const glm::vec3 n =
        glm::cross(mesh.vertices[b] - mesh.vertices[a], mesh.vertices[c] - mesh.vertices[a]);
    mesh.patches.push_back({a, b, c});
    mesh.normal.push_back(glm::normalize(n));
    mesh.area.push_back(0.5f * glm::length(n));
    mesh.material.push_back(material);
    mesh.source_triangle.push_back(static_cast<uint32_t>(mesh.size() - 1));
  }
  // Two patches (a, b, c) and (a, c, d) of the quad a b c d.
  void quad(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, uint32_t material = 0) {
    const uint32_t ia = vertex(a), ib = vertex(b), ic = vertex(c), id = vertex(d);
    patch(ia, ib, ic, material);
    patch(ia, ic, id, material);
  }
};

// The unit-ish quad [-1, 1]^2 at z = 0 facing +z: patch 0 = (v0 v1 v2) below the diagonal
// y = x, patch 1 = (v0 v2 v3) above it.
inline PatchMesh facing_quad() {
  MeshBuilder b;
  b.quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0});
  return b.mesh;
}

// The cube [-1, 1]^3 seen from inside (inward normals), each face n x n quads with welded
// vertices; face f has radiosity wall_value(f). Faces: -x +x -y +y -z +z.
inline glm::vec3 wall_value(int face) {
  static const std::array<glm::vec3, 6> values{glm::vec3(1, 0, 0), glm::vec3(0, 1, 0),
                                               glm::vec3(0, 0, 1), glm::vec3(1, 1, 0),
                                               glm::vec3(0, 1, 1), glm::vec3(1, 0, 1)};
  return values[face];
}

inline std::pair<PatchMesh, std::vector<glm::vec3>> inside_box(int n) {
  const glm::vec3 x(2, 0, 0), y(0, 2, 0), z(0, 0, 2);
  struct Face {
    glm::vec3 origin, u, v;
  };
  const std::array<Face, 6> faces{Face{{-1, -1, -1}, y, z}, Face{{1, -1, -1}, z, y},
                                  Face{{-1, -1, -1}, z, x}, Face{{-1, 1, -1}, x, z},
                                  Face{{-1, -1, -1}, x, y}, Face{{-1, -1, 1}, y, x}};
  MeshBuilder b;
  std::vector<glm::vec3> radiosity;
  for (int f = 0; f < 6; ++f) {
    const Face& face = faces[f];
    const auto first = static_cast<uint32_t>(b.mesh.vertices.size());
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i)
        b.vertex(face.origin + face.u * (float(i) / n) + face.v * (float(j) / n));
    const auto at = [&](int i, int j) { return first + static_cast<uint32_t>(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        b.patch(at(i, j), at(i + 1, j), at(i + 1, j + 1));
        b.patch(at(i, j), at(i + 1, j + 1), at(i, j + 1));
        radiosity.insert(radiosity.end(), 2, wall_value(f));
      }
  }
  return {b.mesh, radiosity};
}

}  // namespace sirad::test
