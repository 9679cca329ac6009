// sirad tests: the OpenCL kernels against the plain C++ reference, bundle for bundle.
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include "engine/bundle.h"
#include "engine/bundle_cl.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "tests/coincident_scenes.h"

namespace sirad {
namespace {

std::vector<glm::vec4> patch_radiance(const PatchMesh& mesh) {
  // A radiance that differs per patch, so a wrong neighbour shows up in the sums.
  std::vector<glm::vec4> r(mesh.size());
  for (std::size_t j = 0; j < r.size(); ++j)
    r[j] = glm::vec4(1.0f + 0.001f * static_cast<float>(j % 997), 2.0f + std::sin(0.1f * j), 0.5f, 0.0f);
  return r;
}

// `base` turned to the frame (u, v, w) with an integer grid offset: lines exactly on the
// grid points where axis-aligned edges fall.
SiradBundle aligned(SiradBundle base, const float (&u)[3], const float (&v)[3], const float (&w)[3]) {
  for (int k = 0; k < 3; ++k) {
    base.u[k] = u[k];
    base.v[k] = v[k];
    base.w[k] = w[k];
  }
  base.offset_x = std::floor(base.offset_x);
  base.offset_y = std::floor(base.offset_y);
  return base;
}

// The wide path adds each patch's crossings in the reference's order: its sums are the same
// bits; the band path adds band by band, so its sums round differently where a patch spans bands.
void expect_same_bundle(const PatchMesh& mesh, BundleEngine& cl, BundleEngine& ref, const SiradBundle& b,
                        TransferPath path = TransferPath::band) {
  auto radiance = patch_radiance(mesh);
  BundleResult a, r;
  cl.run(b, radiance, a);
  ref.run(b, radiance, r);
  ASSERT_EQ(a.crossings, r.crossings);
  ASSERT_GT(r.crossings, 0u);
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    ASSERT_EQ(a.hits[j], r.hits[j]) << "patch " << j;
    if (path == TransferPath::wide) {
      for (int c = 0; c < 3; ++c) ASSERT_EQ(a.gathered[j][c], r.gathered[j][c]) << "patch " << j << " channel " << c;
      continue;
    }
    for (int c = 0; c < 3; ++c) {
      // Sums of up to a few hundred floats in the same order: relative 1e-5 is generous.
      float tol = 1e-5f * std::max(1.0f, std::fabs(r.gathered[j][c]));
      ASSERT_NEAR(a.gathered[j][c], r.gathered[j][c], tol) << "patch " << j << " channel " << c;
    }
  }
}

// The tests below run on both transfer paths (engine/bundle_cl.h), on the same PoCL device.
class BundlePaths : public testing::TestWithParam<TransferPath> {
 protected:
  std::unique_ptr<BundleEngine> engine(const PatchMesh& mesh, ClEngineOptions options = {}) {
    options.path = GetParam();
    return make_cl_engine(mesh, options);
  }
};

INSTANTIATE_TEST_SUITE_P(Paths, BundlePaths, testing::Values(TransferPath::band, TransferPath::wide),
                         [](const testing::TestParamInfo<TransferPath>& info) { return std::string(to_string(info.param)); });

TEST_P(BundlePaths, MatchesReferenceOnCornellRandomBundles) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 800});
  auto cl = engine(mesh);
  auto ref = make_reference_engine(mesh);
  for (uint64_t k = 0; k < 6; ++k) expect_same_bundle(mesh, *cl, *ref, make_bundle(mesh, 96, 7, k), GetParam());
}

TEST_P(BundlePaths, MatchesReferenceOnGrazingAndAxisDirections) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 500});
  auto cl = engine(mesh);
  auto ref = make_reference_engine(mesh);
  SiradBundle base = make_bundle(mesh, 64, 3, 0);
  // Directions along the axes (walls seen exactly edge-on), nearly grazing, and a grid offset
  // that puts lines exactly on cell edges (integer offsets).
  const float dirs[][3] = {{0, 0, 1}, {0, 1, 0}, {1, 0, 0}, {0, 0, -1}, {1e-4f, 1, 0}, {0.70710678f, 0, 0.70710678f}};
  const float frames[][2][3] = {{{1, 0, 0}, {0, 1, 0}}, {{0, 0, 1}, {1, 0, 0}}, {{0, 1, 0}, {0, 0, 1}},
                                {{1, 0, 0}, {0, -1, 0}}, {{0, 0, 1}, {1, -1e-4f, 0}}, {{0, 1, 0}, {-0.70710678f, 0, 0.70710678f}}};
  for (int d = 0; d < 6; ++d) {
    SiradBundle b = aligned(base, frames[d][0], frames[d][1], dirs[d]);
    SCOPED_TRACE(d);
    expect_same_bundle(mesh, *cl, *ref, b, GetParam());
  }
}


// Watertightness: inside the closed furnace cube every line meets the walls in facing pairs,
// so with radiance 1 everywhere each crossing gathers exactly 1: gathered == hits for every
// patch. A crack along a shared edge (a line slipping between two patches) gathers background
// 0 and a line given to both patches breaks the pairing; either makes gathered < hits.
// Checked for random bundles and for axis-aligned ones whose lines run exactly along edges.
TEST_P(BundlePaths, FurnaceIsWatertight) {
  PatchMesh mesh = mesh_scene(builtin_furnace(), {.target_patches = 3000});
  auto cl = engine(mesh);
  std::vector<glm::vec4> one(mesh.size(), glm::vec4(1.0f, 1.0f, 1.0f, 0.0f));
  std::vector<SiradBundle> bundles;
  for (uint64_t k = 0; k < 8; ++k) bundles.push_back(make_bundle(mesh, 200, 21, k));
  SiradBundle axis = make_bundle(mesh, 101, 21, 99);
  const float frame[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int d = 0; d < 3; ++d) bundles.push_back(aligned(axis, frame[(d + 1) % 3], frame[(d + 2) % 3], frame[d]));
  for (std::size_t i = 0; i < bundles.size(); ++i) {
    BundleResult r;
    cl->run(bundles[i], one, r);
    ASSERT_GT(r.crossings, 0u);
    EXPECT_EQ(r.crossings % 2, 0u) << "bundle " << i;
    for (std::size_t j = 0; j < mesh.size(); ++j)
      ASSERT_EQ(r.gathered[j].x, static_cast<float>(r.hits[j])) << "bundle " << i << " patch " << j;
  }
}


// Two runs of one bundle that must agree bit for bit: crossings, hits and every gathered sum.
void expect_identical(const BundleResult& a, const BundleResult& b) {
  EXPECT_EQ(a.crossings, b.crossings);
  EXPECT_EQ(a.hits, b.hits);
  ASSERT_EQ(a.gathered.size(), b.gathered.size());
  EXPECT_EQ(0, std::memcmp(a.gathered.data(), b.gathered.data(), a.gathered.size() * sizeof(glm::vec4)));
}

// A row whose crossings, or a band whose patches, overflow the scratch make the engine grow
// the scratch and run the bundle again: the result is the same as with ample room, bit for
// bit; and the band count does not change the result beyond float summation order.
TEST(BundleKernel, ScratchGrowthAndBandingDoNotChangeResults) {
  PatchMesh mesh = mesh_scene(builtin_furnace(), {.target_patches = 600});
  auto roomy = make_cl_engine(mesh);
  auto tight = make_cl_engine(mesh, {.row_capacity = 4, .list_capacity = 3});
  auto many_bands = make_cl_engine(mesh, {.bands = 37});
  auto radiance = patch_radiance(mesh);
  for (uint64_t k = 0; k < 4; ++k) {
    SiradBundle b = make_bundle(mesh, 80, 5, k);
    BundleResult a, t, m;
    roomy->run(b, radiance, a);
    tight->run(b, radiance, t);
    many_bands->run(b, radiance, m);
    expect_identical(a, t);
    ASSERT_EQ(a.crossings, m.crossings);
    EXPECT_EQ(a.hits, m.hits);
    for (std::size_t j = 0; j < mesh.size(); ++j)
      ASSERT_NEAR(a.gathered[j].x, m.gathered[j].x, 1e-5f * std::max(1.0f, a.gathered[j].x));
  }
}


// The band pass collects crossings in blocks of rows (as many as fit a budget of lines): the
// block height changes neither the crossings nor any sum, bit for bit (each patch still sums
// its lines in row-major order), at grids where the blocks are one row, several rows and
// whole bands, with band heights that do and do not divide by the block height. A block visits
// only the patches that reach it (those still reaching it from earlier blocks and those that
// start in it): checked with patches of a few rows (1,500) and patches spanning whole bands (40).
TEST(BundleKernel, RowBlocksDoNotChangeResults) {
  for (std::size_t patches : {std::size_t{1500}, std::size_t{40}}) {
    SCOPED_TRACE(patches);
    PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = patches});
    auto rows = make_cl_engine(mesh, {.bands = 5, .block_lines = 1});
    auto blocks = make_cl_engine(mesh, {.bands = 5, .block_lines = 700});
    auto whole = make_cl_engine(mesh, {.bands = 5, .block_lines = 1 << 20});
    auto reference = make_reference_engine(mesh);
    auto radiance = patch_radiance(mesh);
    for (int grid : {64, 150, 301}) {
      SiradBundle b = make_bundle(mesh, grid, 11, static_cast<uint64_t>(grid));
      BundleResult ref;
      reference->run(b, radiance, ref);
      BundleResult r, k, w;
      rows->run(b, radiance, r);
      blocks->run(b, radiance, k);
      whole->run(b, radiance, w);
      SCOPED_TRACE(grid);
      expect_identical(r, k);
      expect_identical(r, w);
      ASSERT_EQ(r.crossings, ref.crossings);
      EXPECT_EQ(r.hits, ref.hits);
    }
  }
}


// A thin two-sided wall made of two coincident one-sided faces, alone in empty space: every
// line through it meets the back-facing pair, and each face must look outwards, into the
// background (0). Depths of the two faces come from different vertices and diagonals, so
// they differ by rounding; the tie rule must still order them. Checked for the three ways of
// writing the reversed face, on the kernels and on the reference.
TEST_P(BundlePaths, CoincidentFacesOfAThinWallLookOutwards) {
  for (const char* reversed : {"f 8 7 6 5", "f 6 5 8 7", "f 7 6 5 8"}) {
    SCOPED_TRACE(reversed);
    std::string obj = std::string("mtllib w.mtl\nusemtl wall\nv 0 0 0\nv 3 0.2 0\nv 3.1 2 0.4\nv 0 2 0.4\n") +
                      "v 0 0 0\nv 3 0.2 0\nv 3.1 2 0.4\nv 0 2 0.4\nf 1 2 3 4\n" + reversed + "\n";
    PatchMesh mesh = mesh_scene(parse_obj("wall.obj", obj, {{"w.mtl", "newmtl wall\nKd 0.5 0.5 0.5\nKe 1 1 1\n"}}),
                                {.target_patches = 400});
    auto cl = engine(mesh);
    auto ref = make_reference_engine(mesh);
    std::vector<glm::vec4> one(mesh.size(), glm::vec4(1.0f, 1.0f, 1.0f, 0.0f));
    for (uint64_t k = 0; k < 6; ++k) {
      SiradBundle b = make_bundle(mesh, 128, 17, k);
      for (BundleEngine* e : {cl.get(), ref.get()}) {
        BundleResult r;
        e->run(b, one, r);
        ASSERT_GT(r.crossings, 0u);
        for (std::size_t j = 0; j < mesh.size(); ++j)
          ASSERT_EQ(r.gathered[j].x, 0.0f) << e->description() << ", bundle " << k << ", patch " << j;
      }
    }
  }
}

// The scenes of tests/engine/coincident_test.cpp, bundle for bundle: a zero-thickness wall whose two
// faces are cut differently, at an oblique angle, with T-junctions; a rug on a floor at zero
// gap (which face is on top is decided by patch order, never by rounding); a free-standing
// zero-thickness panel. The kernels and the C++ reference order the faces at one place alike.
TEST_P(BundlePaths, MatchesReferenceOnCoincidentFaces) {
  for (const Scene& scene : {test::two_rooms(0.0, test::oblique(37.0), 3), test::rug_room(0.0, test::oblique(23.0)),
                             test::panel_room(test::oblique(61.0))}) {
    SCOPED_TRACE(scene.name);
    PatchMesh mesh = mesh_scene(scene, {.target_patches = 800});
    auto cl = engine(mesh);
    auto ref = make_reference_engine(mesh);
    for (uint64_t k = 0; k < 6; ++k) expect_same_bundle(mesh, *cl, *ref, make_bundle(mesh, 96, 9, k), GetParam());
  }
}

// A batch of bundles (one launch of each pass on the wide path; the bundles in turn on the band
// path) gives each bundle what it gives alone, bit for bit: the batch's numbering of patches,
// spans, lines and crossings keeps every bundle's own, and no sum crosses bundles. Checked with
// batches of 1, 3 and 8 over a fine mesh and a coarse one, and on the wide path from scratch
// too small for one bundle (grown for the batch).
TEST_P(BundlePaths, ABatchGivesEachBundleItsOwnResult) {
  for (std::size_t patches : {std::size_t{1500}, std::size_t{60}}) {
    SCOPED_TRACE(patches);
    PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = patches});
    auto alone = engine(mesh);
    auto batched = engine(mesh);
    auto tight = engine(mesh, {.span_capacity = 1, .crossing_capacity = 1});
    auto radiance = patch_radiance(mesh);
    for (std::size_t count : {std::size_t{1}, std::size_t{3}, std::size_t{8}}) {
      SCOPED_TRACE(count);
      std::vector<SiradBundle> bundles;
      for (std::size_t k = 0; k < count; ++k) bundles.push_back(make_bundle(mesh, 90, 31, 100 * count + k));
      std::vector<BundleResult> batch(count), small(count);
      batched->run_batch(bundles, radiance, batch);
      tight->run_batch(bundles, radiance, small);
      for (std::size_t k = 0; k < count; ++k) {
        BundleResult one;
        alone->run(bundles[k], radiance, one);
        ASSERT_GT(one.crossings, 0u);
        expect_identical(one, batch[k]);
        expect_identical(one, small[k]);
      }
    }
  }
}

// The wide path's scratch starts as small as one span and one crossing: it grows to what the
// bundles need and runs them again, and the results are those of ample room, bit for bit, at
// grids where a line is crossed by a few patches and by hundreds (a fine mesh, grid 32).
TEST(BundleKernel, WidePathScratchGrowthDoesNotChangeResults) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 3000});
  auto roomy = make_cl_engine(mesh, {.path = TransferPath::wide});
  auto tight = make_cl_engine(mesh, {.path = TransferPath::wide, .span_capacity = 1, .crossing_capacity = 1});
  auto ref = make_reference_engine(mesh);
  auto radiance = patch_radiance(mesh);
  for (int grid : {32, 97, 400}) {
    SCOPED_TRACE(grid);
    SiradBundle b = make_bundle(mesh, grid, 13, static_cast<uint64_t>(grid));
    BundleResult a, t;
    roomy->run(b, radiance, a);
    tight->run(b, radiance, t);
    expect_identical(a, t);
    expect_same_bundle(mesh, *tight, *ref, b, TransferPath::wide);
  }
}

}  // namespace
}  // namespace sirad
