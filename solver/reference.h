// sirad: an independent reference solver for the radiosity model of DESIGN.md section 1.
// It shares no estimator and no rasterisation with the bundle solver: rays are
// cast with Embree 3 from points on each patch, the direct light comes from the exact
// point-to-polygon form factor (Lambert's contour formula) with visibility as a control variate
// (from an emitter a patch mostly does not see, the visible part sampled alone), and the linear system is solved by Gauss-Seidel. Only the mesh, scene loading and outputs are
// shared with the rest of sirad.
//
// The model (the bundle solver's, radiance units, per RGB channel):
//     B_i = E_i + rho_i * (sum_j F_ij B_j + F_i,bg * background)
// A ray leaving patch i's front hits the nearest patch j (either facing; back faces occlude): if
// j shows it its front (dot(n_j, dir) < 0) it brings B_j, if its back, the background, as does a
// ray that leaves the scene. Faces at one place follow the coincident-face rule of DESIGN.md
// section 1 (a face showing its front wins over one showing its back; of faces facing the same
// way the later patch is on top, and a point under it is covered: it gathers the background).
//
// Split B = E + Y (Y: reflected radiance). Then Y = D + rho (F Y + F_bg background) with the
// direct part D_i = rho_i sum_L F_iL E_L over the emitters L. D is estimated from the exact
// unoccluded form factor minus a Monte-Carlo visibility correction (unbiased; zero variance where
// nothing occludes); F from cosine-distributed rays. The rays and light samples are split into
// R independent batches; each batch is solved on its own, the estimate is the mean of the batch
// solutions and its standard error sd(batch solutions) / sqrt(R).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "scene/mesh.h"

namespace sirad {

struct ReferenceOptions {
  int rays_per_patch = 2048;  // cosine-distributed rays per patch, all batches together
  // Points per patch (all batches together) for the direct light: each point takes the exact
  // form factor of every emitting input triangle in front of it and one shadow ray to a stratified
  // point on each of them (the visibility control variate; for a triangle that 8 pilot segments
  // find mostly hidden from the patch, the visible part sampled alone).
  int light_samples = 64;
  int batches = 8;            // independent batches (>= 2 for a standard error)
  uint64_t seed = 1;
  int threads = 0;            // 0: all cores
};

struct ReferenceSolution {
  std::vector<glm::dvec3> radiosity, radiosity_se;  // B = E + Y and its standard error
  std::vector<glm::dvec3> direct, direct_se;        // D = rho sum_L F_iL E_L and its standard error
  uint64_t rays = 0;     // rays cast: indirect and shadow
  double seconds = 0;
  int iterations = 0;    // Gauss-Seidel sweeps of the slowest batch
  bool converged = true; // false if some batch hit the iteration cap (rho = 1 closed scenes)
  int batches = 0;
  // Each batch's solution B_b (mean over b = radiosity), for standard errors of aggregates
  // (sums over patches are correlated, so per-patch errors do not combine). Not in the file.
  std::vector<std::vector<glm::dvec3>> batch_radiosity;
};

// Solves `mesh`. Throws sirad::Error on bad options (rays < batches, batches < 1, ...).
ReferenceSolution solve_reference(const PatchMesh& mesh, const ReferenceOptions& options);

// The area-weighted mean over non-emitting patches of radiosity_se / radiosity (all channels:
// sum A |se| / sum A |B|, |.| the Euclidean norm over RGB): the headline relative error.
double mean_relative_se(const PatchMesh& mesh, const ReferenceSolution& solution);

// NAME.ref.csv: a header with the mesh hash, then one line per patch in patch order:
//   patch,B_r,B_g,B_b,Bse_r,Bse_g,Bse_b,D_r,D_g,D_b,Dse_r,Dse_g,Dse_b
// Written atomically.
void write_reference(const std::string& path, const PatchMesh& mesh, const ReferenceSolution& solution,
                     const ReferenceOptions& options);
// Reads a file written by write_reference for `mesh`. Throws sirad::Error "FILE:LINE: ..." on a
// hash or patch-count mismatch, a short or malformed file, a non-finite or negative value.
ReferenceSolution read_reference(const std::string& path, const PatchMesh& mesh);

}  // namespace sirad
