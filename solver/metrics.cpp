// sirad: error measures between radiosity solutions.
#include "solver/metrics.h"

#include <algorithm>
#include <cmath>

namespace sirad {

double relative_rms(const PatchMesh& mesh, const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b) {
  double num = 0.0, den = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    if (mesh.emits(j)) continue;
    for (int c = 0; c < 3; ++c) {
      double d = static_cast<double>(a[j][c]) - b[j][c];
      num += mesh.area[j] * d * d;
      den += mesh.area[j] * static_cast<double>(b[j][c]) * b[j][c];
    }
  }
  return std::sqrt(num / den);
}

ReferenceError relative_rms_vs_reference(const PatchMesh& mesh, const std::vector<glm::vec3>& a,
                                         const std::vector<glm::dvec3>& ref, const std::vector<glm::dvec3>& ref_se) {
  double num = 0.0, var = 0.0, den = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    if (mesh.emits(j)) continue;
    for (int c = 0; c < 3; ++c) {
      double d = static_cast<double>(a[j][c]) - ref[j][c];
      num += mesh.area[j] * d * d;
      var += mesh.area[j] * ref_se[j][c] * ref_se[j][c];
      den += mesh.area[j] * ref[j][c] * ref[j][c];
    }
  }
  ReferenceError r;
  if (den <= 0.0) return r;
  r.raw = std::sqrt(num / den);
  r.corrected = std::sqrt(std::max(0.0, num - var) / den);
  r.ref_share = std::sqrt(var / den);
  return r;
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
