// sirad tests: the first shot (engine/shot.h, kernels/shot.cl): the kernel against the C++
// reference pixel for pixel, watertightness, the hemicube's weights, and the estimator
// against a closed-form form factor.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "engine/shot.h"
#include "io/read_solution.h"
#include "io/write.h"
#include "solver/reference.h"
#include "tests/coincident_scenes.h"
#include "tests/test_util.h"

namespace sirad {
namespace {

// Compares the kernel's and the reference's images of `shots` shots: every differing sample
// must be one where the two exact methods may differ (an edge within 1e-3 pixel, or a depth
// tie), and those are rare.
void expect_kernel_matches_reference(const PatchMesh& mesh, int resolution, uint64_t shots, double min_seen = 0.25) {
  auto cl = make_cl_shot_engine(mesh);
  auto ref = make_reference_shot_engine(mesh);
  EmitterTable table = emitter_table(mesh);
  std::vector<uint32_t> a, b;
  std::vector<uint8_t> ambiguous;
  std::size_t samples = 0, differ = 0, seen = 0, lost = 0;
  for (uint64_t k = 0; k < shots; ++k) {
    SiradShot shot = make_shot(mesh, draw_shot(mesh, table, 11, k), resolution);
    cl->render(shot, a);
    ref->render(shot, b);
    ASSERT_EQ(a.size(), b.size());
    reference_shot_ambiguity(mesh, shot, 1e-3, ambiguous);
    for (std::size_t i = 0; i < a.size(); ++i) {
      ++samples;
      seen += b[i] != SIRAD_NO_PATCH;
      if (a[i] == b[i]) continue;
      ++differ;
      lost += a[i] == SIRAD_NO_PATCH;  // light the kernel drops where the reference sees a face
      EXPECT_TRUE(ambiguous[i]) << "shot " << k << " sample " << i << ": kernel sees " << a[i]
                                << ", reference " << b[i];
    }
  }
  fmt::print("{} samples, {} see a front face, {} differ (all near an edge or a depth tie)\n", samples, seen, differ);
  EXPECT_GT(static_cast<double>(seen), min_seen * static_cast<double>(samples));  // the comparison is about something
  EXPECT_LE(differ, samples / 1000);
  // Even where an exact tie excuses a difference, the kernel must not lose the surface the
  // reference sees (a thin wall's back face winning the depth test would): at most 1 in 10^4.
  EXPECT_LE(lost, samples / 10000) << lost << " samples lost";
}

// Patches go through the kernels in blocks, the z-buffers kept between them: the image is the
// same bit for bit whatever the block size (here 1200 patches in one block, in blocks of 97, a
// size that splits patches of one face and of one object, and of 1), coincident faces included.
TEST(FirstShot, BlocksOfPatchesGiveTheSameImage) {
  for (const PatchMesh& mesh : {mesh_scene(builtin_cornell(), {.target_patches = 1200}),
                                mesh_scene(test::two_rooms(0.0, test::oblique(20.0), 3), {.target_patches = 600})}) {
    EmitterTable table = emitter_table(mesh);
    auto whole = make_cl_shot_engine(mesh, {}, mesh.size());
    for (std::size_t block : {97, 1}) {
      auto blocked = make_cl_shot_engine(mesh, {}, block);
      std::vector<uint32_t> a, b;
      for (uint64_t k = 0; k < 4; ++k) {
        SiradShot shot = make_shot(mesh, draw_shot(mesh, table, 5, k), 64);
        whole->render(shot, a);
        blocked->render(shot, b);
        ASSERT_EQ(a, b) << "block " << block << ", shot " << k;
      }
    }
  }
}

TEST(FirstShot, KernelMatchesReferenceOnCornell) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 300});
  expect_kernel_matches_reference(mesh, 32, 6);
}

TEST(FirstShot, KernelMatchesReferenceInAnOccludedRoom) {
  // The closed room's block casts shadows; its lamp wall meets the side walls at right angles
  // (geometry close to the eye: clipping at the near plane).
  PatchMesh mesh = mesh_scene(test::closed_room(0.5f), {.target_patches = 400});
  expect_kernel_matches_reference(mesh, 24, 6);
}

TEST(FirstShot, KernelMatchesReferenceWithAThinWall) {
  // A ceiling lamp over a floor and a two-sided partition (one quad twice, opposite windings)
  // standing right under the lamp's middle, up to just below it: the two faces are at one
  // place, so the depth test must keep the one facing the eye, and from eyes on the lamp the
  // partition crosses the near plane of several faces (clipped). A depth plane anchored at a
  // clip point used to lose the facing side on ~1 % of the light here.
  std::string obj = R"(mtllib t.mtl
v 0 0 0
v 4 0 0
v 4 0 4
v 0 0 4
v 1.5 3.9 1.5
v 2.5 3.9 1.5
v 2.5 3.9 2.5
v 1.5 3.9 2.5
v 0.5 0 2
v 3.5 0 2
v 3.5 3.8 2
v 0.5 3.8 2
usemtl grey
f 1 4 3 2
usemtl lamp
f 5 6 7 8
usemtl grey
f 9 10 11 12
f 9 12 11 10
)";
  std::string mtl = "newmtl lamp\nKd 0 0 0\nKe 1 1 1\nnewmtl grey\nKd 0.5 0.5 0.5\n";
  PatchMesh mesh = mesh_scene(parse_obj("thin.obj", obj, {{"t.mtl", mtl}}), {.target_patches = 300});
  expect_kernel_matches_reference(mesh, 48, 8, 0.05);  // open: most of the hemicube sees nothing
}

// A rug on a floor at zero gap (the later patch is on top of a depth tie, never rounding) and
// a zero-thickness wall cut differently on its two sides, at oblique angles.
TEST(FirstShot, KernelMatchesReferenceOnCoincidentFaces) {
  for (const Scene& scene : {test::rug_room(0.0, test::oblique(23.0)), test::two_rooms(0.0, test::oblique(37.0), 3)}) {
    SCOPED_TRACE(scene.name);
    PatchMesh mesh = mesh_scene(scene, {.target_patches = 400});
    expect_kernel_matches_reference(mesh, 32, 6);
  }
}

TEST(FirstShot, FurnaceIsWatertight) {
  // In a closed cube every pixel sample sees a front face: no sample is lost through a shared
  // edge, a clipped corner or a face edge of the hemicube. And by the estimator, every shot's
  // area-weighted mean of D is rho * (sum of the weights), within 0.5 * (0.55 / H + O(h^2))
  // of 0.5 (see HemicubeWeightsIntegrateTheCosine).
  PatchMesh mesh = mesh_scene(builtin_furnace(), {.target_patches = 600});
  auto cl = make_cl_shot_engine(mesh);
  EmitterTable table = emitter_table(mesh);
  ASSERT_EQ(table.patch.size(), mesh.size());
  std::vector<uint32_t> image;
  for (uint64_t k = 0; k < 16; ++k) {
    ShotDraw draw = draw_shot(mesh, table, 3, k);
    SiradShot shot = make_shot(mesh, draw, 48);
    cl->render(shot, image);
    std::size_t lost = 0;
    for (uint32_t j : image) lost += j == SIRAD_NO_PATCH;
    std::vector<double> w = shot_weights(shot);
    std::vector<glm::dvec3> direct(mesh.size(), glm::dvec3(0.0));
    accumulate_shot(mesh, table, draw, shot, image, w, direct);
    EXPECT_EQ(lost, 0u) << "shot " << k;
    double weighted = 0.0, area = 0.0;
    for (std::size_t j = 0; j < mesh.size(); ++j) {
      weighted += mesh.area[j] * direct[j].x;
      area += mesh.area[j];
    }
    EXPECT_NEAR(weighted / area, 0.5, 0.5 * (0.55 / 48 + 2.0 / (48 * 48))) << "shot " << k;
  }
}

TEST(FirstShot, HemicubeWeightsIntegrateTheCosine) {
  // sum dF over the hemicube = (1/pi) integral of cos over the hemisphere = 1. A lattice
  // shifted by j has the rectangle rule's error h (j - 1/2) (g(end) - g(start)) + O(h^2) along
  // each axis (h = 2 / H). The top face's ends cancel by symmetry, and so do the side faces'
  // x ends; along y a side face runs from dF = 0 at the horizon to dF = 1 / (pi (x^2 + 2)^2) at
  // its top edge, whose integral over x in [-1, 1] is 0.1376: so each lattice is within
  // 4 * 0.1376 * h / 2 = 0.55 / H (plus O(h^2)) of 1, and the jitter makes the mean over
  // lattices exact: 64 lattices at H = 16 must average to 1 within 4 standard errors.
  PatchMesh mesh = mesh_scene(builtin_cornell(), {});
  EmitterTable table = emitter_table(mesh);
  double sum = 0.0, sum2 = 0.0;
  const int n = 64;
  for (int k = 0; k < n; ++k) {
    SiradShot shot = make_shot(mesh, draw_shot(mesh, table, 5, k), 16);
    double total = 0.0;
    for (double w : shot_weights(shot)) total += w;
    EXPECT_NEAR(total, 1.0, 0.55 / 16 + 2.0 / (16 * 16));
    sum += total;
    sum2 += total * total;
  }
  double mean = sum / n, sd = std::sqrt(std::max(0.0, sum2 / n - mean * mean));
  fmt::print("hemicube weights at H = 16: mean {:.6f}, sd {:.2e}\n", mean, sd);
  EXPECT_NEAR(mean, 1.0, 4.0 * sd / std::sqrt(n) + 1e-12);
}

// Two directly opposed parallel squares of side a at distance c (Howell's catalogue, C-11):
// F = 2/(pi X Y) [ln sqrt((1+X^2)(1+Y^2)/(1+X^2+Y^2)) + X sqrt(1+Y^2) atan(X/sqrt(1+Y^2))
//      + Y sqrt(1+X^2) atan(Y/sqrt(1+X^2)) - X atan X - Y atan Y],  X = Y = a / c.
double parallel_squares(double a, double c) {
  double X = a / c, Y = a / c;
  double s = std::log(std::sqrt((1 + X * X) * (1 + Y * Y) / (1 + X * X + Y * Y))) +
             X * std::sqrt(1 + Y * Y) * std::atan(X / std::sqrt(1 + Y * Y)) +
             Y * std::sqrt(1 + X * X) * std::atan(Y / std::sqrt(1 + X * X)) - X * std::atan(X) - Y * std::atan(Y);
  return 2.0 / (std::numbers::pi * X * Y) * s;
}

TEST(FirstShot, MatchesTheFormFactorOfParallelSquares) {
  // A square lamp (E = 1) facing down at height 1 over a grey square (rho = 0.5) of side 1:
  // the receiver's area-weighted direct light is rho E F = 0.5 * 0.19982. Per-shot values are
  // independent, so the mean of N has standard error sd / sqrt(N); the test wants the exact
  // value within 4 of those. One shot's value varies by about 11 % (the point-to-square form
  // factor from the lamp's corner against its centre), so 1024 shots give a standard error
  // near 0.35 %: below 0.5 % asserted, so a 2 % bias would show.
  std::string obj = R"(mtllib s.mtl
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
usemtl lamp
f 1 4 3 2
usemtl grey
f 5 6 7 8
)";
  std::string mtl = "newmtl lamp\nKd 0 0 0\nKe 1 1 1\nnewmtl grey\nKd 0.5 0.5 0.5\n";
  PatchMesh mesh = mesh_scene(parse_obj("squares.obj", obj, {{"s.mtl", mtl}}), {.target_patches = 64});
  auto cl = make_cl_shot_engine(mesh);
  const double exact = 0.5 * parallel_squares(1.0, 1.0);
  double receiver_area = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j)
    if (!mesh.emits(j)) receiver_area += mesh.area[j];
  const int n = 1024;
  double sum = 0.0, sum2 = 0.0;
  for (int k = 0; k < n; ++k) {
    ShotSums s = run_shots(mesh, *cl, 32, 9, k, 1);
    double v = 0.0;
    for (std::size_t j = 0; j < mesh.size(); ++j)
      if (!mesh.emits(j)) v += mesh.area[j] * s.direct[j].x;
    v /= receiver_area;
    sum += v;
    sum2 += v * v;
  }
  double mean = sum / n, se = std::sqrt(std::max(0.0, sum2 / n - mean * mean) / (n - 1));
  fmt::print("parallel squares: first shot {:.5f} +- {:.5f}, exact {:.5f}\n", mean, se, exact);
  EXPECT_LT(se, 0.005 * exact);
  EXPECT_NEAR(mean, exact, 4.0 * se);
}

}  // namespace
}  // namespace sirad

namespace sirad {
namespace {

// The first shot alone against the independent reference's direct component D (solver/reference.h:
// exact unoccluded form factors, ray-cast visibility), on scenes with shadows and lights of
// different sizes. Shots are split into G batches; the aggregate (area-weighted over the
// non-emitting patches, all channels) of each batch is independent, so its mean has standard
// error sd / sqrt(G); the reference's SE of the aggregate is at most the area-weighted sum of its
// per-patch SEs (perfect correlation), which is added in quadrature. Pass: |d| < 3 SE, and SE
// below 0.5 % / 3 so that a 0.5 % bias would show. Per patch and channel, z = (D - D_ref) / SE
// with SE^2 = var / G + se_ref^2 (var: the spread of the batch means): for unbiased estimates z
// is close to Student's t with G - 1 = 19 degrees of freedom, P(|z| > 4) = 0.08 %; heavy tails
// (rare shots from a small bright lamp onto its neighbours) make it rarer still, since an
// outlier inflates the estimate and its SE together. Pass: at most 1 % beyond 4. A bias of two
// SEs on every patch would put about 5 % there, a missing shadow far more. (Sums of squares over
// patches are not used: a few tiny patches next to the brightest lamp dominate them.)
// Stratified shots (engine/shot.h): a batch is a whole number of blocks of 64 shots, so batches
// stay independent and everything above holds as it is.
void check_direct(const char* name, const Scene& scene, std::size_t patches, int resolution, int per_batch,
                  bool stratified = false) {
  ASSERT_TRUE(!stratified || per_batch % kShotStrata == 0);
  PatchMesh mesh = mesh_scene(scene, {.target_patches = patches});
  ReferenceSolution ref = solve_reference(mesh, {.rays_per_patch = 64, .light_samples = 4096, .batches = 8, .seed = 5});
  auto cl = make_cl_shot_engine(mesh);
  const int G = 20;
  std::vector<std::vector<glm::dvec3>> batch;
  for (int g = 0; g < G; ++g) {
    ShotSums s = run_shots(mesh, *cl, resolution, 31, static_cast<uint64_t>(g * per_batch), static_cast<uint64_t>(per_batch),
                           Stream::shots, stratified);
    for (auto& v : s.direct) v /= static_cast<double>(s.shots);
    batch.push_back(std::move(s.direct));
  }
  auto aggregate = [&](const std::vector<glm::dvec3>& v) {
    double sum = 0.0;
    for (std::size_t j = 0; j < mesh.size(); ++j)
      if (!mesh.emits(j)) sum += mesh.area[j] * (v[j].x + v[j].y + v[j].z);
    return sum;
  };
  double ref_agg = aggregate(ref.direct), ref_se_agg = aggregate(ref.direct_se);
  double m = 0.0, q = 0.0;
  for (const auto& b : batch) m += aggregate(b) / G;
  for (const auto& b : batch) q += (aggregate(b) - m) * (aggregate(b) - m) / (G - 1);
  double d = m / ref_agg - 1.0, se = std::hypot(std::sqrt(q / G), ref_se_agg) / ref_agg;
  int counted = 0, beyond = 0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    if (mesh.emits(j) || ref.direct[j].x + ref.direct[j].y + ref.direct[j].z <= 0.0) continue;
    for (int c = 0; c < 3; ++c) {
      double mean = 0.0, var = 0.0;
      for (const auto& b : batch) mean += b[j][c] / G;
      for (const auto& b : batch) var += (b[j][c] - mean) * (b[j][c] - mean) / (G - 1);
      double s2 = var / G + ref.direct_se[j][c] * ref.direct_se[j][c];
      if (!(s2 > 0.0)) continue;
      beyond += std::abs(mean - ref.direct[j][c]) > 4.0 * std::sqrt(s2);
      ++counted;
    }
  }
  double outside = static_cast<double>(beyond) / std::max(counted, 1);
  fmt::print("{} direct ({}, {} patches, H {}, {} shots): first shot - reference {:+.3f}% +- {:.3f}% (shots {:.3f}%, "
             "reference {:.3f}%), d / SE {:+.2f}; per patch |z| > 4: {:.3f}% of {} values\n",
             name, stratified ? "stratified" : "random", mesh.size(), resolution, G * per_batch, 100 * d, 100 * se, 100 * std::sqrt(q / G) / ref_agg,
             100 * ref_se_agg / ref_agg, d / se, 100 * outside, counted);
  EXPECT_LT(se, 0.005 / 3) << name;
  EXPECT_LT(std::abs(d), 3 * se) << name;
  EXPECT_LE(outside, 0.01) << name;
}

TEST(FirstShot, MatchesReferenceDirectCornell) { check_direct("cornell", builtin_cornell(), 1200, 48, 52); }
TEST(FirstShot, MatchesReferenceDirectThreeLights) { check_direct("three-lights", builtin_three_lights(), 1000, 32, 512); }
TEST(FirstShot, StratifiedMatchesReferenceDirectCornell) { check_direct("cornell", builtin_cornell(), 1200, 48, 64, true); }
TEST(FirstShot, StratifiedMatchesReferenceDirectThreeLights) {
  check_direct("three-lights", builtin_three_lights(), 1000, 32, 128, true);
}

}  // namespace
}  // namespace sirad

namespace sirad {
namespace {

// The first shot's D from `replicas` disjoint runs of `shots` shots each (shot indices from
// `first` on) against the reference's D: the RMS over replicas of the relative RMS error per
// non-emitting patch (the reference's variance subtracted).
struct Replicas {
  int resolution = 48;
  uint64_t seed = 1, first = 0, shots = 64;
  int replicas = 6;
  bool stratified = false;
};
double replica_error(const PatchMesh& mesh, const ReferenceSolution& ref, ShotEngine& engine, const Replicas& r) {
  double sum2 = 0.0;
  for (int k = 0; k < r.replicas; ++k) {
    ShotSums s = run_shots(mesh, engine, r.resolution, r.seed, r.first + static_cast<uint64_t>(k) * r.shots, r.shots,
                           Stream::shots, r.stratified);
    std::vector<glm::vec3> d(mesh.size());
    for (std::size_t j = 0; j < d.size(); ++j) d[j] = glm::vec3(s.direct[j] / static_cast<double>(s.shots));
    double e = relative_rms_vs_reference(mesh, d, ref.direct, ref.direct_se).corrected;
    sum2 += e * e / r.replicas;
  }
  return std::sqrt(sum2);
}

TEST(FirstShot, ErrorFallsWithItsOwnSampleCount) {
  // The first shot's D from N and from 4N shots against the reference's D (its own variance
  // subtracted): for an unbiased estimator with finite variance the relative RMS error falls as
  // 1 / sqrt(N), a ratio of 2. One run's error is a sum over ~1200 patches x 3 channels of
  // squared errors, but they are correlated through the shared light samples (a shot lights half
  // the room), so one realisation scatters widely (a single pair gave 3.0): the mean squared
  // error over 6 disjoint replicas of each size is compared, ratio within [1.5, 2.7]; a bias
  // would flatten it towards 1.
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 1200});
  ReferenceSolution ref = solve_reference(mesh, {.rays_per_patch = 64, .light_samples = 4096, .batches = 8, .seed = 8});
  auto cl = make_cl_shot_engine(mesh);
  double e1 = replica_error(mesh, ref, *cl, {.resolution = 48, .seed = 77, .first = 0, .shots = 64, .replicas = 6});
  double e4 = replica_error(mesh, ref, *cl, {.resolution = 48, .seed = 77, .first = 6 * 64, .shots = 256, .replicas = 6});
  fmt::print("first shot alone: error {:.4f} at 64 shots, {:.4f} at 256 (ratio {:.2f})\n", e1, e4, e1 / e4);
  EXPECT_GT(e1 / e4, 1.5);
  EXPECT_LT(e1 / e4, 2.7);
}

}  // namespace
}  // namespace sirad

namespace sirad {
namespace {

// Stratified points on the lights (engine/shot.h) against random ones: 8 disjoint replicas of
// 256 shots each (4 whole blocks), Cornell at 1200 patches, H 96 (about 16 pixel samples per
// median patch, so that the point's noise, where on the light a shot stands, dominates: the
// light's nearness to the ceiling and the penumbrae). Mean squared error against the
// reference's D (its variance subtracted) over the replicas, for each sampling; the strata must
// bring it down. Measured: 0.0139 random, 0.0055 stratified (ratio 0.40). The replicas' squared errors scatter by ~25 % each (shared
// light samples correlate the patches), so the mean of 8 by ~9 %, the ratio of the two RMS
// errors by ~6 %: we require < 0.8.
TEST(FirstShot, StratifiedPointsLowerTheError) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 1200});
  ReferenceSolution ref = solve_reference(mesh, {.rays_per_patch = 64, .light_samples = 4096, .batches = 8, .seed = 8});
  auto cl = make_cl_shot_engine(mesh);
  const Replicas replicas{.resolution = 96, .seed = 78, .first = 0, .shots = 256, .replicas = 8};
  double random = replica_error(mesh, ref, *cl, replicas);
  Replicas strata = replicas;
  strata.stratified = true;
  double stratified = replica_error(mesh, ref, *cl, strata);
  fmt::print("first shot alone, 8 x 256 shots at H 96: error {:.4f} random, {:.4f} stratified (ratio {:.2f})\n", random,
             stratified, stratified / random);
  EXPECT_LT(stratified / random, 0.8);
}

}  // namespace
}  // namespace sirad

namespace sirad {
namespace {

// The shot leaves to the bundles the lights that their receivers do not see alike from every
// point (engine/shot.h shot_emitter_table): a lamp 1.5 cm under a ceiling, made two-sided as
// Blender exports it, is shot from its lower side only; its upper side, which lights the gap, stays
// in what the bundles carry. The Cornell box's light, 0.1 mm under its ceiling but facing down, is
// shot whole.
TEST(FirstShot, LightsThatLightANearSurfaceAreLeftToTheBundles) {
  const PatchMesh mesh = mesh_scene(test::lamp_under_ceiling(0.015), {.target_patches = 3000});
  std::vector<double> incoherence;
  const EmitterTable table = shot_emitter_table(mesh, &incoherence);
  std::size_t down = 0, up = 0;
  for (std::size_t j = 0; j < mesh.size(); ++j)
    if (mesh.emits(j)) (mesh.normal[j].y < 0 ? down : up) += 1;
  ASSERT_GT(down, 0u);
  ASSERT_GT(up, 0u);
  EXPECT_EQ(table.patch.size(), down);
  for (uint32_t j : table.patch) EXPECT_LT(mesh.normal[j].y, 0.0f) << j;
  ASSERT_EQ(incoherence.size(), 2u);  // the two sides, each one parallelogram
  EXPECT_GT(std::max(incoherence[0], incoherence[1]), 0.9);
  EXPECT_LT(std::min(incoherence[0], incoherence[1]), 0.1);

  const PatchMesh cornell = mesh_scene(builtin_cornell(), {.target_patches = 1200});
  const EmitterTable all = emitter_table(cornell), shot = shot_emitter_table(cornell);
  EXPECT_EQ(shot.patch, all.patch);
  EXPECT_EQ(shot.cdf, all.cdf);
}


// A lamp 1.5 cm under a ceiling, two-sided: the ceiling is cut along the lamp's outline (scene/scene.h
// cut_along_gaps), so that no ceiling triangle, and so no patch, lies partly over the lamp
// (where the gap's light is trapped) and partly beside it. The ceiling keeps its area.
TEST(GapCuts, ACeilingOverALampIsCutAlongItsOutline) {
  const Scene s = test::lamp_under_ceiling(0.015);
  double over = 0.0, beside = 0.0;
  std::size_t ceiling = 0;
  for (const Triangle& t : s.triangles) {
    const glm::dvec3 n = glm::cross(glm::dvec3(t.p[1] - t.p[0]), glm::dvec3(t.p[2] - t.p[0]));
    if (!(std::abs(t.p[0].y - 3.0f) < 1e-6f && n.y < 0.0)) continue;  // the ceiling faces down
    ++ceiling;
    int in = 0;
    for (const glm::vec3& p : t.p) in += p.x >= 1.4f - 1e-5f && p.x <= 2.6f + 1e-5f && p.z >= 1.7f - 1e-5f && p.z <= 2.3f + 1e-5f;
    const glm::vec3 c = (t.p[0] + t.p[1] + t.p[2]) / 3.0f;
    const bool centre_in = c.x > 1.4f && c.x < 2.6f && c.z > 1.7f && c.z < 2.3f;
    EXPECT_EQ(in == 3, centre_in) << c.x << " " << c.z;
    EXPECT_EQ(t.in_gap, centre_in) << c.x << " " << c.z;  // the pieces over the lamp are marked
    (centre_in ? over : beside) += 0.5 * glm::length(n);
  }
  EXPECT_GT(ceiling, 2u);
  EXPECT_NEAR(over, 1.2 * 0.6, 1e-5);
  EXPECT_NEAR(over + beside, 4.0 * 4.0, 1e-4);
  // 40 cm below the ceiling (more than a quarter of the lamp's diagonal) nothing is cut.
  const Scene far = test::lamp_under_ceiling(0.4);
  std::size_t far_ceiling = 0;
  for (const Triangle& t : far.triangles) far_ceiling += std::abs(t.p[0].y - 3.0f) < 1e-6f && std::abs(t.p[1].y - 3.0f) < 1e-6f;
  EXPECT_EQ(far_ceiling, 2u);
}

// Where the gap is wide enough to matter (kGapStripsFrom of the lamp's extent), strips along the
// rim are cut too: on the ceiling from kGapStripsIn.back() x g inside the lamp's outline to
// kGapStripsOut.back() x g outside it, on the lamp's upper side within kGapStripsEmitter.back() x g
// of its rim. They are Triangle::whole, so the mesher leaves each one patch; nothing else is whole,
// and every surface keeps its area. Below kGapStripsFrom only the outline is cut.
TEST(GapCuts, StripsAlongALampsRimAreAsWideAsTheGap) {
  const double g = 0.015;
  const Scene s = test::lamp_under_ceiling(g);
  // How far a point lies outside the lamp's outline (x 1.4..2.6, z 1.7..2.3; negative inside):
  // the outline moved out by d is where this is d (its corners mitred, as the cuts make them).
  auto outside = [](const glm::dvec3& p) { return std::max({1.4 - p.x, p.x - 2.6, 1.7 - p.z, p.z - 2.3}); };
  const double out = kGapStripsOut.back() * g, in = kGapStripsIn.back() * g, lamp_in = kGapStripsEmitter.back() * g;
  auto rect = [](double grow) { return (1.2 + 2 * grow) * (0.6 + 2 * grow); };
  double ceiling_strips = 0.0, lamp_strips = 0.0, ceiling = 0.0, lamp_up = 0.0;
  std::size_t whole = 0;
  for (const Triangle& t : s.triangles) {
    const glm::dvec3 a(t.p[0]), b(t.p[1]), c(t.p[2]);
    const glm::dvec3 n = glm::cross(b - a, c - a);
    const double area = 0.5 * glm::length(n), d = outside((a + b + c) / 3.0);
    const bool on_ceiling = std::abs(a.y - 3.0) < 1e-6 && n.y < 0.0, lamp_top = std::abs(a.y - (3.0 - g)) < 1e-6 && n.y > 0.0;
    whole += t.whole;
    if (on_ceiling) {
      ceiling += area;
      EXPECT_EQ(t.whole, d > -in && d < out) << "ceiling piece at " << d << " m from the outline";
      if (t.whole) ceiling_strips += area;
    } else if (lamp_top) {
      lamp_up += area;
      EXPECT_EQ(t.whole, d > -lamp_in) << "lamp piece at " << d << " m from its rim";
      if (t.whole) lamp_strips += area;
    } else {
      EXPECT_FALSE(t.whole) << "a triangle at y " << a.y;
    }
  }
  EXPECT_NEAR(ceiling, 16.0, 1e-4);
  EXPECT_NEAR(lamp_up, rect(0.0), 1e-5);
  EXPECT_NEAR(ceiling_strips, rect(out) - rect(-in), 1e-5);
  // The lamp's diagonal runs through two of its corners and cuts a triangle of (2g)^2 / 2 off the
  // strip there, under kGapStripLeast x g x extent: it stays with the piece beside it, at most two.
  EXPECT_LE(std::abs(lamp_strips - (rect(0.0) - rect(-lamp_in))), lamp_in * lamp_in + 1e-5);
  EXPECT_LT(lamp_in * lamp_in / 2, kGapStripLeast * g * std::hypot(1.2, 0.6));
  // Each strip is one patch, however fine the rest of the mesh.
  const PatchMesh mesh = mesh_scene(s, {.target_patches = 20000});
  std::size_t strip_patches = 0;
  for (std::size_t j = 0; j < mesh.size(); ++j) strip_patches += s.triangles[mesh.source_triangle[j]].whole;
  EXPECT_EQ(strip_patches, whole);
  // 1 mm under the ceiling (under 1/256 of the lamp's 1.34 m) the outline is cut, no strips.
  const Scene thin = test::lamp_under_ceiling(0.001);
  EXPECT_TRUE(std::any_of(thin.triangles.begin(), thin.triangles.end(), [](const Triangle& t) { return t.in_gap; }));
  EXPECT_TRUE(std::none_of(thin.triangles.begin(), thin.triangles.end(), [](const Triangle& t) { return t.whole; }));
}

// The corner values that images, outputs and the final gather interpolate never blend the light
// over a lamp into the ceiling beside it (PatchMesh::in_gap), also once the solution is read back
// from its PLY: with 100 over the lamp and 1 elsewhere, every corner of a patch beside it is 1,
// where a corner on the outline would otherwise take a mean of the two.
TEST(GapCuts, CornerValuesDoNotBlendAcrossALampsOutline) {
  const PatchMesh mesh = mesh_scene(test::lamp_under_ceiling(0.015), {.target_patches = 3000});
  ASSERT_EQ(mesh.in_gap.size(), mesh.size());
  std::vector<glm::vec3> b(mesh.size(), glm::vec3(1.0f));
  std::size_t over = 0, beside_at_outline = 0;
  for (std::size_t j = 0; j < mesh.size(); ++j) over += mesh.in_gap[j], b[j] = mesh.in_gap[j] ? glm::vec3(100.0f) : b[j];
  ASSERT_GT(over, 10u);
  const std::string ply = ::testing::TempDir() + "gap_corners.ply";
  write_ply(ply, mesh, b);
  const Solution back = read_solution(ply);
  ASSERT_EQ(back.mesh.size(), mesh.size());
  for (const auto& corners : {corner_radiosity(mesh, b), back.corners}) {
    for (std::size_t j = 0; j < mesh.size(); ++j) {
      const bool on_outline = std::any_of(mesh.patches[j].begin(), mesh.patches[j].end(), [&](uint32_t v) {
        const glm::vec3 p = mesh.vertices[v];
        return std::abs(p.y - 3.0f) < 1e-6f && p.x >= 1.4f - 1e-5f && p.x <= 2.6f + 1e-5f && p.z >= 1.7f - 1e-5f && p.z <= 2.3f + 1e-5f;
      });
      if (mesh.in_gap[j] || mesh.emits(j) || !on_outline) continue;
      ++beside_at_outline;
      for (const glm::vec3& c : corners[j]) EXPECT_EQ(c, glm::vec3(1.0f)) << "patch " << j;
    }
  }
  // Beside the outline lies the strip outside it, one patch per piece: at least the two
  // triangles of each side's piece, in each of the two loops.
  EXPECT_GE(beside_at_outline, 2u * 4u * 2u);
  std::filesystem::remove(ply);
}

}  // namespace
}  // namespace sirad
