// sirad: a solution read back (see solution.h).
#include "io/read_solution.h"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "io/write.h"
#include "scene/gltf.h"
#include "scene/ply.h"
#include "util/error.h"

namespace sirad {

Solution read_solution(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  Solution s;
  if (ext == ".glb" || ext == ".gltf") {
    std::vector<std::array<glm::vec3, 3>> per_triangle;
    Scene scene = import_gltf(path, {}, &per_triangle);
    s.mesh = mesh_scene(scene, MeshOptions{});  // one patch per triangle, its corners in order
    s.camera_aspect = scene.camera_aspect;
    s.corners.resize(s.mesh.size());
    for (std::size_t j = 0; j < s.mesh.size(); ++j) {
      const uint32_t t = s.mesh.source_triangle[j];
      if (t >= per_triangle.size()) fail("{}: patch {} has no triangle", path, j);
      s.corners[j] = per_triangle[t];
    }
    s.radiosity.resize(s.mesh.size());
    for (std::size_t j = 0; j < s.mesh.size(); ++j) s.radiosity[j] = (s.corners[j][0] + s.corners[j][1] + s.corners[j][2]) / 3.0f;
    return s;
  }
  if (ext != ".ply") fail("{}: not a solution sirad reads (a .ply or .glb it wrote)", path);
  std::vector<glm::vec3> per_triangle;
  double error = -1.0;
  Scene scene = import_ply(path, {}, &per_triangle, &error);
  if (error >= 0.0) s.error_estimate = error;
  s.mesh = mesh_scene(scene, MeshOptions{});  // one patch per triangle: the faces as written
  s.radiosity.resize(s.mesh.size());
  for (std::size_t j = 0; j < s.mesh.size(); ++j) {
    const uint32_t t = s.mesh.source_triangle[j];
    if (t >= per_triangle.size()) fail("{}: patch {} has no face", path, j);
    s.radiosity[j] = per_triangle[t];
  }
  s.corners = corner_radiosity(s.mesh, s.radiosity);
  return s;
}

}  // namespace sirad
