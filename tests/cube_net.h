// sirad tests: a lightmap UV set (Scene::uv_maps, as glTF TEXCOORD_1 gives one) for the faces of
// the unit cube, laid out as a net: the four walls a strip around v in [0.25, 0.5] (y = 0, x = 1,
// y = 1, x = 0, left to right), the floor (z = 0) above the y = 0 wall and the ceiling (z = 1)
// below it, each face 0.25 on a side. Faces that meet in the net share their edge's UV, so the
// six are one island (curved: it folds at five edges); the strip's ends (x = 0, y = 0) meet in
// 3D but not in the net.
#pragma once
#include <array>
#include <cmath>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "scene/scene.h"

namespace sirad::test {

// Point p of the face whose coordinate `axis` is `side` (0 or 1): its place in the net.
inline glm::dvec2 cube_net_uv(const glm::dvec3& p, int axis, int side) {
  const double x = p.x, y = p.y, z = p.z;
  if (axis == 2) return side == 0 ? glm::dvec2(x / 4, 0.25 - y / 4) : glm::dvec2(x / 4, 0.5 + y / 4);
  const double v = 0.25 + z / 4;
  if (axis == 1) return side == 0 ? glm::dvec2(x / 4, v) : glm::dvec2((3 - x) / 4, v);
  return side == 1 ? glm::dvec2((1 + y) / 4, v) : glm::dvec2((4 - y) / 4, v);
}

// Gives every triangle of `scene` that lies on a face of the unit cube its map in the net.
inline void give_cube_net_uv(Scene& scene) {
  for (Triangle& t : scene.triangles)
    for (int axis = 0; axis < 3; ++axis) {
      if (t.p[0][axis] != t.p[1][axis] || t.p[0][axis] != t.p[2][axis] || (t.p[0][axis] != 0.0f && t.p[0][axis] != 1.0f)) continue;
      const int side = t.p[0][axis] == 0.0f ? 0 : 1;
      std::array<glm::dvec3, 3> p;
      std::array<glm::dvec2, 3> uv;
      for (std::size_t k = 0; k < 3; ++k) p[k] = glm::dvec3(t.p[k]), uv[k] = cube_net_uv(p[k], axis, side);
      UvMap map;
      if (!make_uv_map(p, uv, map)) continue;
      t.uv_map = static_cast<uint32_t>(scene.uv_maps.size());
      scene.uv_maps.push_back(map);
      break;
    }
}

}  // namespace sirad::test
