// sirad: the paper's model's scene parameters measured on a real mesh with real bundles:
// the contraction a, the first bounce's relative deviation
// sigma_1 / C, and the time of one iteration T_i on this engine. The model itself
// (model/model.h) stays pure arithmetic; this is the part that runs kernels.
#pragma once
#include <cstdint>

#include "engine/bundle.h"
#include "scene/mesh.h"

namespace sirad::model {

struct SceneFit {
  double contraction = 0;     // a: energy of bounce k+1 over bounce k (k >= 1)
  double contraction_se = 0;  // its standard error from the spread over chains
  double sigma_ratio = 0;     // sigma_1 / C of one bundle's first bounce
  double t_iteration = 0;     // seconds per bundle on `engine` (median)
  uint64_t bundles = 0;       // bundles run for the fit
};

struct FitOptions {
  uint64_t seed = 1;
  int grid = 0;           // 0: auto_grid
  int chains = 128;       // power iterations from E for a (each `bounces` bundles long;
                          // bright-room: SE ~0.017 at 128, ~0.05 at 16)
  int bounces = 6;        // bounces per chain: ratios e_(k+1) / e_k for k = 1 .. bounces - 1
  int first_bounce = 64;  // one-bundle estimates of the first bounce for sigma_1 / C
};

// Contraction: chains X_0 = E, X_(k+1) = rho T*_k X_k (one fresh bundle per bounce, no
// emission added, with the constant control variate: the mean of X_k), energies e_k = sum_j A_j (X_k,j summed over channels);
// a = sum over chains and k >= 1 of e_(k+1) / the same sum of e_k (a ratio of sums: the
// 1-bounce C is left out, the paper's a relates bounce k+1 to bounce k). In a closed room of
// one albedo rho, T maps a constant to rho times it, so a = rho; openings and dark walls lower it.
// sigma_1 / C: over `first_bounce` bundles, the per-patch variance v_j and mean m_j of rho T* E;
// sqrt(sum A v / sum A) / (sum A m / sum A) (channels summed), over patches with rho > 0.
// Throws sirad::Error for a mesh that emits or reflects nothing.
SceneFit fit_scene(const PatchMesh& mesh, BundleEngine& engine, const FitOptions& options = {});

}  // namespace sirad::model
