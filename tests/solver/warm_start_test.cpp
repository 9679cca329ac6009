// sirad tests: a run that starts from the last one (solver/warm_start.h): patches matched by
// place, one bounding sphere for both meshes, an unchanged scene kept exactly, and after an edit
// (the closed room's block moved) the new scene's answer, its error as estimated, and less of it
// than a cold start of the same length.
#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "solver/reference.h"
#include "solver/warm_start.h"
#include "tests/test_util.h"
#include "util/error.h"

namespace sirad::test {
namespace {

// The closed room (4 m, its ceiling the lamp) with its block made a 0.5 m cube (a piece of
// furniture) at (1.25 + dx, 0.5, 1.25): the block's triangles are those off the room's walls.
Scene room_with_block_at(float dx) {
  Scene s = closed_room(0.7f);
  for (Triangle& t : s.triangles) {
    const bool wall = std::any_of(t.p.begin(), t.p.end(), [](const glm::vec3& v) {
      return v.x == 0.0f || v.x == 4.0f || v.y == 0.0f || v.y == 4.0f || v.z == 0.0f || v.z == 4.0f;
    });
    if (!wall)
      for (glm::vec3& v : t.p) v = glm::vec3(1.0f + dx, 0.5f, 1.0f) + (v - glm::vec3(1.0f, 0.5f, 1.0f)) / 3.0f;
  }
  return s;
}

TEST(WarmStart, PatchesAreMatchedByPlaceNotIndex) {
  PatchMesh before = mesh_scene(room_with_block_at(0.0f), {.target_patches = 400});
  PatchMesh now = before;
  // The patches in another order, each listing its corners from another one; one turned over.
  std::reverse(now.patches.begin(), now.patches.end());
  std::reverse(now.material.begin(), now.material.end());
  for (auto& p : now.patches) std::rotate(p.begin(), p.begin() + 1, p.end());
  std::swap(now.patches[0][1], now.patches[0][2]);
  const std::vector<int64_t> match = match_patches(now, before, 1e-6 * before.bound_radius);
  const std::size_t n = now.size();
  EXPECT_EQ(match[0], -1) << "the other winding is the other side: not the same patch";
  for (std::size_t j = 1; j < n; ++j) EXPECT_EQ(match[j], static_cast<int64_t>(n - 1 - j)) << j;
  // The block moved: its patches are new, the room's (but where the block's shadow falls, the
  // same mesh) are the old ones.
  PatchMesh moved = mesh_scene(room_with_block_at(0.5f), {.target_patches = 400});
  const std::vector<int64_t> m2 = match_patches(moved, before, 1e-6 * before.bound_radius);
  std::size_t block = 0, matched = 0;
  for (std::size_t j = 0; j < moved.size(); ++j) {
    const bool on_block = std::all_of(moved.patches[j].begin(), moved.patches[j].end(), [&](uint32_t v) {
      const glm::vec3 p = moved.vertices[v];
      return p.x > 0.0f && p.x < 4.0f && p.y > 0.0f && p.y < 4.0f && p.z > 0.0f && p.z < 4.0f;
    });
    block += on_block;
    if (m2[j] >= 0) {
      ++matched;
      EXPECT_FALSE(on_block) << j;
    }
  }
  EXPECT_GT(block, 0u);
  EXPECT_EQ(matched, moved.size() - block);
  EXPECT_THROW(match_patches(moved, before, 0.0), Error);
}

TEST(WarmStart, TheSharedSphereHoldsBothMeshes) {
  PatchMesh a = mesh_scene(room_with_block_at(0.0f), {.target_patches = 100});
  PatchMesh b = a;
  for (glm::vec3& v : b.vertices) v += glm::vec3(3.0f, -1.0f, 0.5f);
  b.bound_center += glm::vec3(3.0f, -1.0f, 0.5f);
  share_bound(a, b);
  EXPECT_EQ(a.bound_center, b.bound_center);
  EXPECT_EQ(a.bound_radius, b.bound_radius);
  for (const PatchMesh* m : {&a, &b})
    for (const glm::vec3& v : m->vertices) EXPECT_LE(glm::length(glm::dvec3(v) - glm::dvec3(a.bound_center)), a.bound_radius);
  // The smallest such sphere: half the span of the two spheres.
  EXPECT_NEAR(a.bound_radius, (glm::length(glm::vec3(3.0f, -1.0f, 0.5f)) + 2.0 * std::sqrt(12.0)) / 2.0, 1e-3);
}

// From its own solution an unchanged scene does not move: each bundle's lines carry the same
// through both meshes, so the control variate cancels the transport to the last bit.
TEST(WarmStart, AnUnchangedSceneKeepsItsSolution) {
  PatchMesh mesh = mesh_scene(room_with_block_at(0.0f), {.target_patches = 400});
  auto engine = make_cl_engine(mesh);
  const std::vector<glm::vec3> p = solve(mesh, *engine, {.seed = 3}, 64).estimate();
  PatchMesh before = mesh;
  share_bound(mesh, before);
  auto new_engine = make_cl_engine(mesh), old_engine = make_cl_engine(before);
  WarmStart w{.before = &before, .radiosity = p, .engine = old_engine.get(),
              .match = match_patches(mesh, before, 1e-6 * mesh.bound_radius), .error = 0.01};
  const std::vector<glm::vec3> again = solve(mesh, *new_engine, {.seed = 5, .warm = &w}, 32).estimate();
  for (std::size_t j = 0; j < mesh.size(); ++j)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(again[j][c], p[j][c], 1e-6f * std::max(p[j][c], 1e-3f)) << j;
}

// The block moved by 1 m, the run started from a solution of the room before (4,096 bundles)
// and run for 256 more, against an independent reference of the room after (4,096 rays and 1,024
// light points a patch): the relative RMS error per patch, the reference's own noise taken out.
// The warm run's error is P's, carried, and its own: its estimate sqrt(e_P^2 + e_own^2) must hold
// within the factor 1.5 of the issue either way (as the cold estimate is held:
// error_estimate_test.cpp). A cold run of the same 256 bundles has about 4 times P's error
// (4,096 / 256 bundles), the warm one little more than P's: measured 0.18 to 0.34 of the cold
// run's over four pairs of seeds (and the estimate 0.80 to 1.15 of the measured), so at most half.
// A control variate that did not take the moved block's lines out of P's light would leave its
// old shadow on the floor: tens of per cent on those patches, far past either bound.
TEST(WarmStart, AfterAnEditTheAnswerIsTheNewScenesWithLessError) {
  PatchMesh before = mesh_scene(room_with_block_at(0.0f), {.target_patches = 800});
  PatchMesh after = mesh_scene(room_with_block_at(1.0f), {.target_patches = 800});
  SolverOptions first{.seed = 3};
  first.track_error = true;
  double p_error = 0.0;
  std::vector<glm::vec3> p;
  {
    auto engine = make_cl_engine(before);
    Solver s = solve(before, *engine, first, 4096);
    p = s.estimate();
    p_error = s.error_estimate();
  }
  ReferenceSolution ref = solve_reference(after, {.rays_per_patch = 4096, .light_samples = 1024, .batches = 8, .seed = 9});
  SolverOptions cold{.seed = 11};
  cold.track_error = true;
  auto cold_engine = make_cl_engine(after);
  const Solver c = solve(after, *cold_engine, cold, 256);
  const double cold_measured = relative_rms_vs_reference(after, c.estimate(), ref.radiosity, ref.radiosity_se).corrected;

  share_bound(after, before);
  auto new_engine = make_cl_engine(after), old_engine = make_cl_engine(before);
  WarmStart w{.before = &before, .radiosity = p, .engine = old_engine.get(),
              .match = match_patches(after, before, 1e-6 * after.bound_radius), .error = p_error};
  SolverOptions warm{.seed = 11, .warm = &w};
  warm.track_error = true;
  const Solver s = solve(after, *new_engine, warm, 256);
  const double measured = relative_rms_vs_reference(after, s.estimate(), ref.radiosity, ref.radiosity_se).corrected;
  const double estimate = s.error_estimate();
  fmt::print("P's error {:.4f}; 256 bundles: warm estimate {:.4f}, measured {:.4f}; cold estimate {:.4f}, measured {:.4f}\n",
             p_error, estimate, measured, c.error_estimate(), cold_measured);
  EXPECT_GT(estimate / measured, 1.0 / 1.5);
  EXPECT_LT(estimate / measured, 1.5);
  EXPECT_LT(measured, 0.5 * cold_measured);
}

}  // namespace
}  // namespace sirad::test
