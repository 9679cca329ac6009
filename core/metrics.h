// sirad: error measures between radiosity solutions, shared by tests and benchmarks.
#pragma once
#include <vector>

#include <glm/vec3.hpp>

#include "core/mesh.h"

namespace sirad {

// Area-weighted relative RMS difference of `a` against the reference `b` over the patches that
// do not emit, all three channels: sqrt(sum A |a - b|^2 / sum A |b|^2).
double relative_rms(const PatchMesh& mesh, const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b);

// Area-weighted mean of one channel over all patches.
double area_mean(const PatchMesh& mesh, const std::vector<glm::vec3>& value, int channel = 0);

}  // namespace sirad
