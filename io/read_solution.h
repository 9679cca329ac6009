// sirad: a solution read back, so a scene solved once (on the farm, say) can be imaged later and
// anywhere, for any number of cameras (sirad image; render/gather.h).
#pragma once
#include <array>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include <optional>

#include "scene/mesh.h"

namespace sirad {

struct Solution {
  PatchMesh mesh;                    // one patch per face (triangle) of the file, in its order
  // The solution as the final gather interpolates it: at each patch's corners (io/write.h
  // corner_radiosity). From a PLY, made from its per-face radiosity; from a glTF, its _RADIANCE.
  std::vector<std::array<glm::vec3, 3>> corners;
  // Per patch: a PLY's faces as written; from a glTF, which holds only the corners, their mean.
  std::vector<glm::vec3> radiosity;
  // The camera's width / height, where the file says (a glb sirad wrote: the run's image shape).
  std::optional<double> camera_aspect;
  // The run's own error estimate, where the file says (a PLY's `sirad error estimate E`).
  std::optional<double> error_estimate;
};

// A solution sirad wrote, by the file's extension:
//   - .ply (io/write.h write_ply): faces with radiosity, reflectance and emission; the
//     scene's camera and background in its comments. A PLY without radiosity_r/g/b is a scene,
//     not a solution.
//   - .glb or .gltf (io/write_gltf.h write_glb): the triangles with their corners' _RADIANCE,
//     the materials' reflectance and emission, the camera and the background in its extras.
// Throws sirad::Error naming the file for anything else.
Solution read_solution(const std::string& path);

}  // namespace sirad
