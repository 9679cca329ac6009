// sirad: a solution read back, so a scene solved once (on the farm, say) can be imaged later and
// anywhere, for any number of cameras (sirad image; core/gather.h).
#pragma once
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/mesh.h"

namespace sirad {

struct Solution {
  PatchMesh mesh;                    // one patch per face of the file, in its order
  std::vector<glm::vec3> radiosity;  // per patch
};

// The PLY sirad writes (core/output.h write_ply: faces with radiosity, reflectance and
// emission; the scene's camera and background in its comments). Throws sirad::Error naming the
// file for anything else: a PLY without radiosity_r/g/b is a scene, not a solution.
Solution read_solution(const std::string& path);

}  // namespace sirad
