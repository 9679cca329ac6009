// sirad tests: shared helpers (small scenes, statistics over patch values).
#pragma once
#include <cmath>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "engine/bundle_cl.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "solver/metrics.h"
#include "solver/solver.h"

namespace sirad::test {

// Runs `bundles` counted bundles 0..bundles-1 of one run on the default OpenCL device.
inline Solver solve(const PatchMesh& mesh, BundleEngine& engine, const SolverOptions& options, uint64_t bundles) {
  Solver solver(mesh, engine, options);
  for (uint64_t k = 0; k < bundles; ++k) solver.step(k);
  return solver;
}

// solve() in the solver's batches (Solver::step_batch; options.batch, else the engine's).
inline Solver solve_batched(const PatchMesh& mesh, BundleEngine& engine, const SolverOptions& options, uint64_t bundles) {
  Solver solver(mesh, engine, options);
  for (uint64_t k = 0; k < bundles;) {
    const auto count = static_cast<uint32_t>(std::min<uint64_t>(solver.batch(), bundles - k));
    solver.step_batch(k, count);
    k += count;
  }
  return solver;
}

// A closed room (cube of side 4, inward normals) with one emitting wall (Ke 1) and a closed
// block inside (outward normals), every surface with reflectance rho.
inline Scene closed_room(float rho) {
  std::string obj = R"(mtllib room.mtl
v 0 0 0
v 4 0 0
v 4 4 0
v 0 4 0
v 0 0 4
v 4 0 4
v 4 4 4
v 0 4 4
usemtl lamp
f 4 3 7 8
usemtl wall
f 1 5 6 2
f 1 2 3 4
f 5 8 7 6
f 1 4 8 5
f 2 6 7 3
v 1 0.5 1
v 2.5 0.5 1
v 2.5 2 1
v 1 2 1
v 1 0.5 2.5
v 2.5 0.5 2.5
v 2.5 2 2.5
v 1 2 2.5
f 9 12 11 10
f 13 14 15 16
f 9 10 14 13
f 12 16 15 11
f 9 13 16 12
f 10 11 15 14
)";
  std::string rho_s = std::to_string(rho);
  std::string mtl = "newmtl lamp\nKd " + rho_s + " " + rho_s + " " + rho_s + "\nKe 1 1 1\n" +
                    "newmtl wall\nKd " + rho_s + " " + rho_s + " " + rho_s + "\nKe 0 0 0\n";
  return parse_obj("closed_room.obj", obj, {{"room.mtl", mtl}});
}

}  // namespace sirad::test
