// sirad: a solution read back (see solution.h).
#include "core/solution.h"

#include "core/error.h"
#include "core/scene_ply.h"

namespace sirad {

Solution read_solution(const std::string& path) {
  std::vector<glm::vec3> per_triangle;
  Scene scene = import_ply(path, {}, &per_triangle);
  Solution s;
  s.mesh = mesh_scene(scene, MeshOptions{});  // one patch per triangle: the faces as written
  s.radiosity.resize(s.mesh.size());
  for (std::size_t j = 0; j < s.mesh.size(); ++j) {
    const uint32_t t = s.mesh.source_triangle[j];
    if (t >= per_triangle.size()) fail("{}: patch {} has no face", path, j);
    s.radiosity[j] = per_triangle[t];
  }
  return s;
}

}  // namespace sirad
