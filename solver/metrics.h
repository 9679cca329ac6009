// sirad: error measures between radiosity solutions, shared by tests and benchmarks.
#pragma once
#include <vector>

#include <glm/vec3.hpp>

#include "scene/mesh.h"

namespace sirad {

// Area-weighted relative RMS difference of `a` against the reference `b` over the patches that
// do not emit, all three channels: sqrt(sum A |a - b|^2 / sum A |b|^2).
double relative_rms(const PatchMesh& mesh, const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b);

// The error measure against a noisy reference `ref` with per-patch standard errors
// `ref_se`: area-weighted relative RMS over the non-emitting patches, all three channels.
// raw = sqrt(sum A |a - ref|^2 / sum A |ref|^2). If a's errors are independent of ref's,
// E|a - ref|^2 = |a - B|^2 + Var(ref), so `corrected` subtracts sum A |ref_se|^2 from the
// numerator (clamped at 0): an unbiased estimate of the squared error against the exact B.
// `ref_share` = sqrt(sum A |ref_se|^2 / sum A |ref|^2), the part the reference's noise explains.
struct ReferenceError {
  double raw = 0.0, corrected = 0.0, ref_share = 0.0;
};
ReferenceError relative_rms_vs_reference(const PatchMesh& mesh, const std::vector<glm::vec3>& a,
                                         const std::vector<glm::dvec3>& ref, const std::vector<glm::dvec3>& ref_se);

// Area-weighted mean of one channel over all patches.
double area_mean(const PatchMesh& mesh, const std::vector<glm::vec3>& value, int channel = 0);

}  // namespace sirad
