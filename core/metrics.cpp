// sirad: error measures between radiosity solutions.
#include "core/metrics.h"

#include <cmath>

namespace sirad {

double relative_rms(const PatchMesh& mesh, const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b) {
  double num = 0.0, den = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    glm::vec3 e = mesh.emission(j);
    if (e.x > 0 || e.y > 0 || e.z > 0) continue;
    for (int c = 0; c < 3; ++c) {
      double d = static_cast<double>(a[j][c]) - b[j][c];
      num += mesh.area[j] * d * d;
      den += mesh.area[j] * static_cast<double>(b[j][c]) * b[j][c];
    }
  }
  return std::sqrt(num / den);
}

double area_mean(const PatchMesh& mesh, const std::vector<glm::vec3>& value, int channel) {
  double s = 0.0, a = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    s += static_cast<double>(mesh.area[j]) * value[j][channel];
    a += mesh.area[j];
  }
  return s / a;
}

}  // namespace sirad
