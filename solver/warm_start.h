// sirad: a run that starts from the last one (a rebake after an edit: DESIGN.md section 1, "Warm
// start"). The previous solution P, on the previous run's own patches, is a control variate: where
// a patch of the new mesh is one of the old mesh's (matched by its corners' positions, not its
// index), each bundle's estimate there subtracts what the same bundle's lines carry in the old
// scene and adds back what P says they carry on average,
//     L'(m)_j = E_j + rho_j I*_j(L'(m-1)) + (P_i - E_i - rho_i I*_i,old(P))       (i: j's old patch)
// The bracket's mean is P's residual in the old scene, -(I - T_old) eps (eps: P's error), so the
// run's answer is the new scene's fixed point plus (I - T')^-1 (I - T_old) eps ~ eps: unbiased over
// the previous run's randomness, and as good as P where nothing changed. Its noise is what the
// two scenes' lines carry differently (lines that cross what moved) plus the new light's own, far
// less than a cold start's.
#pragma once
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "engine/bundle.h"
#include "scene/mesh.h"

namespace sirad {

struct WarmStart {
  const PatchMesh* before = nullptr;  // the previous run's patches (share_bound with the new mesh)
  std::vector<glm::vec3> radiosity;   // P on them
  BundleEngine* engine = nullptr;     // runs the same bundles on `before`
  std::vector<int64_t> match;         // per patch of the new mesh: its patch of `before`, or -1
  double error = 0.0;                 // P's own error estimate (relative RMS per patch, as error_estimate)
};

// For each patch of `now`, the patch of `before` with the same three corners in the same winding
// (any rotation), each within `tolerance` of a grid point the other also rounds to, or -1. A
// mesh made again from an unchanged surface has the same corners bit for bit.
std::vector<int64_t> match_patches(const PatchMesh& now, const PatchMesh& before, double tolerance);

// Gives both meshes one bounding sphere, the smallest holding both of theirs: a bundle drawn for
// either is then the same lines in both (make_bundle frames its grid by the sphere).
void share_bound(PatchMesh& a, PatchMesh& b);

}  // namespace sirad
