// sirad tests: lightmaps baked from a solution (render/bake.h): a floor's texels under a square
// light against the closed form, no light through a zero-thickness wall into a dark room, no
// samples inside a solid standing on a floor, gutters filled from their own chart, and the same
// lightmap on any number of threads; and the rest of the leak suite: a free-standing panel's
// back, the floor under a rug at zero gap; a file's own UV layout, folded over a cube.
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "render/bake.h"
#include "render/gather.h"
#include "scene/atlas.h"
#include "scene/mesh.h"
#include "tests/closed_forms.h"
#include "tests/cube_net.h"
#include "tests/quad_scene.h"
#include "util/error.h"

namespace sirad {
namespace {

using test::QuadScene;
using test::floor_radiance;

// The solution of two rooms either side of x = 1: B = 1 (plus the emission) on the left, and on
// the wall's side that faces it (normal -x); 0 on the right.
std::vector<glm::vec3> lit_left_dark_right(const PatchMesh& mesh) {
  std::vector<glm::vec3> radiosity(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const auto& p = mesh.patches[j];
    const glm::vec3 centre = (mesh.vertices[p[0]] + mesh.vertices[p[1]] + mesh.vertices[p[2]]) / 3.0f;
    const bool left = centre.x < 1.0f || (centre.x == 1.0f && mesh.normal[j].x < 0);
    radiosity[j] = left ? glm::vec3(1.0f) + mesh.emission(j) : glm::vec3(0.0f);
  }
  return radiosity;
}

// A floor (rho 0.5, 4 x 4 at z = 0 facing +z; triangles 0 and 1) under a unit square light
// (E 1, rho 0; triangles 2 and 3) at height 1, facing down.
QuadScene floor_under_square_light() {
  QuadScene q;
  const uint32_t floor = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
  const uint32_t light = q.material(glm::vec3(0.0f), glm::vec3(1.0f));
  q.quad({-2, -2, 0}, {2, -2, 0}, {2, 2, 0}, {-2, 2, 0}, floor);
  q.quad({-0.5f, -0.5f, 1}, {-0.5f, 0.5f, 1}, {0.5f, 0.5f, 1}, {0.5f, -0.5f, 1}, light);
  return q;
}

// The solution B = E of `mesh`.
std::vector<glm::vec3> emission_only(const PatchMesh& mesh) {
  std::vector<glm::vec3> b(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) b[j] = mesh.emission(j);
  return b;
}

// A floor (rho 0.5, 4 x 4 at z = 0 facing +z) under a unit square light (E 1, rho 0) at height 1,
// facing down; the solution B = E (the floor sees no floor: nothing of B's reflected part
// reaches a floor point, so any floor value would do). A floor texel's value is rho E F over
// its square: per sample the direct estimate D is at most 2 M (M = rho E A / (pi r^2), r >= 1
// the height: each MIS term is at most rho E cos cos A / (pi r^2)), so Var D <= E[D^2] <= 2 M mu
// and a texel of N samples is within 5 sqrt(2 M mu / N) of mu but with probability 6e-7 (normal
// approximation of a mean of 256 bounded terms); 64 texels: 4e-5. With k emitter samples a
// sample each of the k terms is at most 1 / k of that bound (their MIS weights count k), so the
// same bound holds.
TEST(Bake, AFloorsTexelsUnderASquareLightMatchTheClosedForm) {
  QuadScene q = floor_under_square_light();
  const PatchMesh mesh = mesh_scene(q.scene, {.target_patches = 400});
  const FinalGather gather(mesh, emission_only(mesh), {.seed = 5});
  const Atlas atlas = make_atlas(q.scene, {.texel_size = 0.5, .gutter = 2});
  const int samples = 256;
  for (int lights : {1, 4}) {  // 4 emitter samples a sample: the counts' MIS stays unbiased
  SCOPED_TRACE(fmt::format("{} emitter samples a sample", lights));
  const Lightmap m = bake_lightmap(q.scene, atlas, gather, samples, lights);
  const Chart& c = atlas.charts[atlas.chart_of[0]];
  ASSERT_EQ(c.width, 8 + 4);
  ASSERT_EQ(c.height, 8 + 4);
  const double M = 0.5 * 1.0 * 1.0 / std::numbers::pi;
  int checked = 0;
  double squared_error = 0, squared_estimate = 0;
  for (int y = c.y + 2; y < c.y + c.height - 2; ++y)
    for (int x = c.x + 2; x < c.x + c.width - 2; ++x) {
      double mu = 0;  // the closed form's mean over the texel's square, 8 x 8 points
      for (int j = 0; j < 8; ++j)
        for (int i = 0; i < 8; ++i) {
          const glm::dvec3 p = c.origin + c.u * ((x - c.x - 2 + (i + 0.5) / 8) * atlas.texel_size) +
                               c.v * ((y - c.y - 2 + (j + 0.5) / 8) * atlas.texel_size);
          mu += floor_radiance(p.x, p.y, -0.5, 0.5, -0.5, 0.5, 1.0, 0.5, 1.0) / 64;
        }
      const float got = m.combined.at(x, y).x;
      EXPECT_EQ(m.coverage[static_cast<std::size_t>(y) * atlas.width + x], 1.0f);
      EXPECT_NEAR(got, mu, 5 * std::sqrt(2 * M * mu / samples)) << x << ", " << y;
      EXPECT_EQ(m.indirect.at(x, y).x, 0.0f);  // gather rays meet the light's front (B - E = 0) or leave
      squared_error += (got - mu) * (got - mu);
      squared_estimate += double(m.error.at(x, y).x) * m.error.at(x, y).x;
      ++checked;
    }
  EXPECT_EQ(checked, 64);
  // The texels' error estimates against their true errors: each sum is about its texels' mean
  // variance times a chi-square of 64 degrees over 64 (the estimate's terms one degree each, the
  // errors' too: a mean of 256 bounded terms is near normal), so each is within about 18 % of
  // it (sqrt(2 / 64)) and their ratio's logarithm has a standard deviation of about 0.25: a
  // factor of 4 either way is 5.5 of them.
  EXPECT_GT(squared_estimate, 0.0);
  EXPECT_GT(squared_error / squared_estimate, 0.25);
  EXPECT_LT(squared_error / squared_estimate, 4.0);
  // The gutter's texels: no sample of theirs lands on the floor; each takes its chart's nearest.
  EXPECT_EQ(m.coverage[static_cast<std::size_t>(c.y) * atlas.width + c.x], 0.0f);
  EXPECT_EQ(m.combined.at(c.x, c.y), m.combined.at(c.x + 2, c.y + 2));
  }
}

// Two closed rooms side by side sharing a zero-thickness wall (two planes back to back at
// x = 1), the left one lit by its ceiling and every surface of it given B = 1 by the solution,
// the right one dark (B = 0) with a solid block standing on its floor. No texel of the right
// room takes any light (exactly 0: its samples' shadow rays all meet the wall, its gather rays
// all land on surfaces of B = 0); every texel of the left room does (each only where all its
// samples are on one side); the right floor's samples
// under the block are left out (coverage 0 where a texel lies wholly under it, 1 where wholly
// outside). And the lightmap is the same on one thread and on four.
TEST(Bake, NoLightThroughAThinWallAndNoSamplesInsideASolid) {
  QuadScene q;
  const uint32_t white = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
  const uint32_t lamp = q.material(glm::vec3(0.5f), glm::vec3(2.0f));
  auto room = [&](float x0, bool lit) {  // the inside of [x0, x0 + 1] x [0, 1] x [0, 1]
    const float x1 = x0 + 1;
    q.quad({x0, 0, 0}, {x1, 0, 0}, {x1, 1, 0}, {x0, 1, 0}, white);            // floor, +z
    q.quad({x0, 0, 1}, {x0, 1, 1}, {x1, 1, 1}, {x1, 0, 1}, lit ? lamp : white);  // ceiling, -z
    q.quad({x0, 0, 0}, {x0, 0, 1}, {x1, 0, 1}, {x1, 0, 0}, white);            // y = 0, +y
    q.quad({x0, 1, 0}, {x1, 1, 0}, {x1, 1, 1}, {x0, 1, 1}, white);            // y = 1, -y
    q.quad({x0, 0, 0}, {x0, 1, 0}, {x0, 1, 1}, {x0, 0, 1}, white);            // x = x0, +x
    q.quad({x1, 0, 0}, {x1, 0, 1}, {x1, 1, 1}, {x1, 1, 0}, white);            // x = x1, -x
  };
  room(0, true);
  room(1, false);
  // A block 0.4 x 0.4 x 0.3 on the right room's floor, its outside faces (its bottom on the floor).
  const float a = 1.3f, b = 1.7f, lo = 0.3f, hi = 0.7f, h = 0.3f;
  q.quad({a, lo, 0}, {a, hi, 0}, {b, hi, 0}, {b, lo, 0}, white);  // bottom, -z
  q.quad({a, lo, h}, {b, lo, h}, {b, hi, h}, {a, hi, h}, white);  // top, +z
  q.quad({a, lo, 0}, {b, lo, 0}, {b, lo, h}, {a, lo, h}, white);  // -y
  q.quad({a, hi, 0}, {a, hi, h}, {b, hi, h}, {b, hi, 0}, white);  // +y
  q.quad({a, lo, 0}, {a, lo, h}, {a, hi, h}, {a, hi, 0}, white);  // -x
  q.quad({b, lo, 0}, {b, hi, 0}, {b, hi, h}, {b, lo, h}, white);  // +x
  const PatchMesh mesh = mesh_scene(q.scene, {.target_patches = 2000});
  const std::vector<glm::vec3> radiosity = lit_left_dark_right(mesh);
  const Atlas atlas = make_atlas(q.scene, {.texel_size = 0.05, .gutter = 1});
  const FinalGather one(mesh, radiosity, {.seed = 2, .threads = 1}), four(mesh, radiosity, {.seed = 2, .threads = 4});
  const Lightmap m = bake_lightmap(q.scene, atlas, one, 16);
  // Every texel wholly on a surface (all its samples kept) and wholly in one room (the two
  // rooms' floors share an edge in one plane, but the wall stands on it: two charts).
  int lit = 0, dark = 0;
  for (const Chart& c : atlas.charts)
    for (int y = c.y; y < c.y + c.height; ++y)
      for (int x = c.x; x < c.x + c.width; ++x) {
        if (m.coverage[static_cast<std::size_t>(y) * atlas.width + x] < 1.0f) continue;
        double x_lo = INFINITY, x_hi = -INFINITY;
        for (int k = 0; k < 4; ++k) {
          const glm::dvec3 p =
              c.origin + c.u * ((x - c.x - 1 + (k & 1)) * atlas.texel_size) + c.v * ((y - c.y - 1 + (k >> 1)) * atlas.texel_size);
          x_lo = std::min(x_lo, p.x), x_hi = std::max(x_hi, p.x);
        }
        const bool on_wall = x_hi - x_lo < 1e-6 && std::abs(x_lo - 1.0) < 1e-6;  // the shared wall: by its side
        const bool left = on_wall ? c.normal.x < 0 : x_hi <= 1.0 + 1e-6;
        const bool right = on_wall ? c.normal.x > 0 : x_lo >= 1.0 - 1e-6;
        const glm::vec3 v = m.combined.at(x, y);
        if (left) {
          EXPECT_GT(v.x, 0.0f) << "a texel of the lit room at " << x << ", " << y;
          ++lit;
        } else if (right) {
          EXPECT_EQ(v, glm::vec3(0.0f)) << "light in the dark room at texel " << x << ", " << y << " (direct "
                                        << m.direct.at(x, y).x << ", indirect " << m.indirect.at(x, y).x << ")";
          ++dark;
        }
      }
  EXPECT_GT(lit, 2000);
  EXPECT_GT(dark, 2000);
  // The right room's floor (faces 12, 13): texels wholly under the block have no sample, those
  // wholly clear of it all of theirs.
  const Chart& f = atlas.charts[atlas.chart_of[12]];
  int under = 0, clear = 0;
  for (int y = f.y + 1; y < f.y + f.height - 1; ++y)
    for (int x = f.x + 1; x < f.x + f.width - 1; ++x) {
      glm::dvec3 corner[4];
      for (int k = 0; k < 4; ++k)
        corner[k] = f.origin + f.u * ((x - f.x - 1 + (k & 1)) * atlas.texel_size) + f.v * ((y - f.y - 1 + (k >> 1)) * atlas.texel_size);
      const auto in_block = [&](const glm::dvec3& p) { return p.x > a && p.x < b && p.y > lo && p.y < hi; };
      const float coverage = m.coverage[static_cast<std::size_t>(y) * atlas.width + x];
      if (std::any_of(corner, corner + 4, [](const glm::dvec3& p) { return p.x < 1.0 || p.x > 2.0; })) continue;
      if (std::all_of(corner, corner + 4, in_block)) {
        EXPECT_EQ(coverage, 0.0f) << x << ", " << y;
        ++under;
      } else if (std::none_of(corner, corner + 4, in_block)) {
        EXPECT_EQ(coverage, 1.0f) << x << ", " << y;
        ++clear;
      }
    }
  EXPECT_GT(under, 30);
  EXPECT_GT(clear, 200);
  // Any number of threads: the same lightmap, bit for bit.
  const Lightmap again = bake_lightmap(q.scene, atlas, four, 16);
  EXPECT_EQ(again.combined.pixels, m.combined.pixels);
  EXPECT_EQ(again.coverage, m.coverage);
  EXPECT_THROW(bake_lightmap(q.scene, atlas, one, 0), Error);
}

// The furnace (a closed unit cube, E = 1, rho = 0.5 everywhere, B = 2): every gather ray from a
// face's middle meets a face whose light beyond its emission is B - E = 1 (none lands close
// enough to trace a bounce further), so a texel's indirect light is rho x 1 = 0.5 exactly,
// whether its chart's cache gives it (records of 256 rays blended) or its own samples' rays do;
// and most texels take the cache (the blocks there are flat and far from everything).
TEST(Bake, TheCachesIndirectLightInTheFurnaceIsExact) {
  const Scene scene = builtin_furnace();
  const PatchMesh mesh = mesh_scene(scene, {.target_patches = 2000});
  std::vector<glm::vec3> b(mesh.size(), glm::vec3(2.0f));
  const FinalGather gather(mesh, b, {.seed = 4});
  const Atlas atlas = make_atlas(scene, {.texel_size = 0.02, .gutter = 1});
  const Lightmap m = bake_lightmap(scene, atlas, gather, 4);
  int checked = 0, covered = 0;
  for (const Chart& c : atlas.charts)
    for (int y = c.y; y < c.y + c.height; ++y)
      for (int x = c.x; x < c.x + c.width; ++x) {
        covered += m.coverage[static_cast<std::size_t>(y) * atlas.width + x] > 0;
        const glm::dvec3 centre = c.origin + c.u * ((x - c.x - 0.5) * atlas.texel_size) + c.v * ((y - c.y - 0.5) * atlas.texel_size);
        bool middle = true;  // 0.35 from every edge of its face
        for (int k = 0; k < 3; ++k)
          if (std::abs(c.normal[k]) < 0.5) middle = middle && centre[k] > 0.35 && centre[k] < 0.65;
        if (!middle) continue;
        for (int k = 0; k < 3; ++k) ASSERT_NEAR(m.indirect.at(x, y)[k], 0.5f, 1e-6f) << x << ", " << y;
        ++checked;
      }
  EXPECT_GT(checked, 6 * 200);
  EXPECT_GT(m.cached, static_cast<uint64_t>(covered) / 2) << covered << " texels with samples";
}

// The furnace again, laid out in the file's UV set as a net (tests/cube_net.h): one chart that
// folds at five edges. Every texel in the middle of a face takes the exact indirect light (from
// the cache, whose records there take their own face's normal, or its own rays), each
// texel of the net has samples on its own face (coverage 1 where the net covers it wholly), and
// texels beside the net are filled from it and those beyond stay empty.
TEST(Bake, AFilesFoldedLayoutBakesEachTexelOnItsOwnFace) {
  Scene scene = builtin_furnace();
  test::give_cube_net_uv(scene);
  const PatchMesh mesh = mesh_scene(scene, {.target_patches = 2000});
  std::vector<glm::vec3> b(mesh.size(), glm::vec3(2.0f));
  const FinalGather gather(mesh, b, {.seed = 4});
  const Atlas atlas = make_atlas(scene, {.texel_size = 0.02, .gutter = 1});
  ASSERT_EQ(atlas.file_width, 200);
  ASSERT_EQ(atlas.charts.size(), 1u);
  const Lightmap m = bake_lightmap(scene, atlas, gather, 4);
  // Whether texel (x, y) lies on a face of the net (50 texels a face).
  const auto face = [](int x, int y) { return x >= 0 && y >= 0 && x < 200 && (y / 50 == 1 || (x < 50 && (y < 50 || (y >= 100 && y < 150)))); };
  int checked = 0, whole = 0, empty = 0, beyond = 0, gutter = 0;
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 200; ++x) {
      const std::size_t k = static_cast<std::size_t>(y) * 200 + static_cast<std::size_t>(x);
      const int sx = x % 50, sy = y % 50;
      if (!face(x, y)) {
        bool near = false;  // the gutter: next to a face's texel
        for (int d = 0; d < 9; ++d) near = near || face(x + d % 3 - 1, y + d / 3 - 1);
        if (near) {
          gutter += atlas.owner[k] == 0 && m.coverage[k] == 0.0f && m.combined.pixels[k].x > 0.0f;
        } else {
          ++beyond;
          empty += atlas.owner[k] == kNoChart && m.coverage[k] == 0.0f && m.combined.pixels[k] == glm::vec3(0.0f);
        }
        continue;
      }
      EXPECT_EQ(atlas.owner[k], 0u) << x << ", " << y;
      whole += m.coverage[k] == 1.0f;
      if (sx < 18 || sx >= 32 || sy < 18 || sy >= 32) continue;  // 0.36 from every edge of its face
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(m.indirect.pixels[k][c], 0.5f, 1e-6f) << x << ", " << y;
      ++checked;
    }
  EXPECT_EQ(checked, 6 * 14 * 14);
  EXPECT_EQ(whole, 6 * 50 * 50);
  // Beside the floor (x = 50) and above the strip (y = 49); below the strip (y = 100), beside the
  // ceiling and under it (y = 150).
  EXPECT_EQ(gutter, (50 + 149) + (150 + 49 + 51));
  EXPECT_EQ(empty, beyond);
  EXPECT_GT(m.cached, static_cast<uint64_t>(whole) / 2);
}

// A floor under a square light (as above), its two triangles two islands of the file's UV set,
// the second turned a quarter: their diagonal is a seam. Baked as is, the two sides' bilinear
// lookups along it differ by the texels' noise (64 samples: several per cent); matched, they
// agree to a thousandth at any point (matched at points a quarter texel apart; between those,
// two bilinear grids turned to each other can differ a little), and texels beyond a lookup's
// reach of the seam (1.5 texels) keep their bits.
TEST(Bake, TheTwoSidesOfASeamAgree) {
  QuadScene q = floor_under_square_light();
  // Islands: the floor's first triangle at [0.05, 0.45]^2, its second turned (u from y, v from
  // x) at [0.55, 0.95] x [0.05, 0.45], the light at [0.05, 0.45] x [0.55, 0.95].
  const auto first = [](const glm::dvec3& p) { return glm::dvec2(0.05 + (p.x + 2) / 10, 0.05 + (p.y + 2) / 10); };
  const auto second = [](const glm::dvec3& p) { return glm::dvec2(0.55 + (p.y + 2) / 10, 0.05 + (p.x + 2) / 10); };
  const auto lamp = [](const glm::dvec3& p) { return glm::dvec2(0.05 + (p.x + 0.5) * 0.4, 0.55 + (p.y + 0.5) * 0.4); };
  for (std::size_t t = 0; t < 4; ++t) {
    Triangle& tri = q.scene.triangles[t];
    std::array<glm::dvec3, 3> p;
    std::array<glm::dvec2, 3> uv;
    for (std::size_t k = 0; k < 3; ++k) p[k] = glm::dvec3(tri.p[k]), uv[k] = t == 0 ? first(p[k]) : t == 1 ? second(p[k]) : lamp(p[k]);
    UvMap map;
    ASSERT_TRUE(make_uv_map(p, uv, map));
    tri.uv_map = static_cast<uint32_t>(q.scene.uv_maps.size());
    q.scene.uv_maps.push_back(map);
  }
  const PatchMesh mesh = mesh_scene(q.scene, {.target_patches = 400});
  const FinalGather gather(mesh, emission_only(mesh), {.seed = 5});
  const Atlas atlas = make_atlas(q.scene, {.texel_size = 0.1, .gutter = 1});
  ASSERT_GT(atlas.file_width, 60);
  ASSERT_EQ(atlas.seams.size(), 1u);  // the light's diagonal is one place in its island
  const Lightmap raw = bake_lightmap(q.scene, atlas, gather, 64, 1, false);
  const Lightmap matched = bake_lightmap(q.scene, atlas, gather, 64, 1, true);
  const double side = atlas.file_width;
  // The bilinear lookup of `m` at UV `uv` (texel centres at half-integers).
  const auto lookup = [&](const Lightmap& m, const glm::dvec2& uv) {
    const double x = uv.x * side - 0.5, y = uv.y * side - 0.5;
    const int i = static_cast<int>(std::floor(x)), j = static_cast<int>(std::floor(y));
    const double fx = x - i, fy = y - j;
    const auto at = [&](int a, int c) { return double(m.combined.at(a, c).x); };
    return (1 - fy) * ((1 - fx) * at(i, j) + fx * at(i + 1, j)) + fy * ((1 - fx) * at(i, j + 1) + fx * at(i + 1, j + 1));
  };
  double raw_worst = 0, matched_worst = 0;
  for (int s = 0; s < 64; ++s) {
    const double t = (s + 0.5) / 64;
    const glm::dvec3 p(-2 + 4 * t, -2 + 4 * t, 0);
    const double a = lookup(raw, first(p)), c = lookup(raw, second(p));
    raw_worst = std::max(raw_worst, std::abs(a - c) / (a + c));
    const double ma = lookup(matched, first(p)), mc = lookup(matched, second(p));
    matched_worst = std::max(matched_worst, std::abs(ma - mc) / (ma + mc));

  }
  EXPECT_GT(raw_worst, 0.01);
  EXPECT_LT(matched_worst, 1e-3);
  // Texels whose centres lie 1.5 texels or more from the seam (the diagonal x = y in each
  // island's own frame) are as baked.
  int kept = 0;
  for (int y = 0; y < atlas.height; ++y)
    for (int x = 0; x < atlas.width; ++x) {
      const double u = (x + 0.5) / side, v = (y + 0.5) / side;
      const double off = u < 0.5 ? std::abs((u - 0.05) - (v - 0.05)) : std::abs((u - 0.55) - (v - 0.05));
      if (off * side / std::sqrt(2.0) < 1.5 + 1.5) continue;
      ASSERT_EQ(matched.combined.at(x, y), raw.combined.at(x, y)) << x << ", " << y;
      ++kept;
    }
  EXPECT_GT(kept, atlas.width * atlas.height / 2);
}

// A texel whose indirect light the chart's cache gives asks `leaving` for the direct light
// alone: the same bits as the full call's direct light (the gather rays go the same ways and
// meet the same emitters), no indirect light, and fewer rays (no bounce traced further where a
// gather ray lands near). Points on the Cornell box's floor, on a grid that runs up to the walls
// and the blocks' feet (where rays land near), with 1 and 3 emitter samples a point.
TEST(Bake, TheDirectLightAloneIsTheFullCallsToTheBit) {
  const PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 1000});
  std::vector<glm::vec3> b(mesh.size(), glm::vec3(0.3f));
  const FinalGather gather(mesh, b, {.seed = 7});
  std::vector<FinalGather::SurfacePoint> points;
  for (int i = 0; i < 24; ++i)
    for (int j = 0; j < 24; ++j)
      points.push_back({.x = {2.0 + 548.0 * i / 23.0, 0.0, 2.0 + 555.0 * j / 23.0}, .normal = {0.0, 1.0, 0.0},
                        .rho = {0.7, 0.7, 0.7}, .emission = {0.0, 0.0, 0.0}});
  for (int lights : {1, 3}) {
    glm::dvec3 full_direct, full_indirect, direct, indirect;
    uint64_t full_cast = 0, cast = 0;
    gather.leaving(points, 11, full_direct, full_indirect, full_cast, lights, true);
    gather.leaving(points, 11, direct, indirect, cast, lights, false);
    EXPECT_EQ(direct, full_direct) << lights;
    EXPECT_GT(full_direct.x, 0.0) << lights;
    EXPECT_EQ(indirect, glm::dvec3(0.0)) << lights;
    EXPECT_GT(full_indirect.x, 0.0) << lights;
    EXPECT_LT(cast, full_cast) << lights;
  }
}

// One floor and one ceiling slab run under and over a zero-thickness wall (two one-sided
// planes back to back at x = 1) between a lit room (its ceiling the lamp, its surfaces B = 1)
// and a dark one (B = 0). Baked on the faces as they come, the floor is one chart and its texels
// across the wall's foot take samples of both rooms: light in the dark room. Cut along the
// contacts (cut_at_contacts), no chart reaches across x = 1, and every texel of the dark
// room's charts, gutters and dilated texels included, is exactly 0.
TEST(Bake, FacesCutAtAWallsFootKeepTwoRoomsTexelsApart) {
  QuadScene q;
  const uint32_t white = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
  const uint32_t lamp = q.material(glm::vec3(0.5f), glm::vec3(2.0f));
  q.quad({0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {0, 1, 0}, white);  // the floor slab, +z
  q.quad({0, 0, 1}, {0, 1, 1}, {1, 1, 1}, {1, 0, 1}, lamp);   // the lit room's ceiling, -z
  q.quad({1, 0, 1}, {1, 1, 1}, {2, 1, 1}, {2, 0, 1}, white);  // the dark room's, -z
  q.quad({0, 0, 0}, {0, 0, 1}, {2, 0, 1}, {2, 0, 0}, white);  // y = 0, +y
  q.quad({0, 1, 0}, {2, 1, 0}, {2, 1, 1}, {0, 1, 1}, white);  // y = 1, -y
  q.quad({0, 0, 0}, {0, 1, 0}, {0, 1, 1}, {0, 0, 1}, white);  // x = 0, +x
  q.quad({2, 0, 0}, {2, 0, 1}, {2, 1, 1}, {2, 1, 0}, white);  // x = 2, -x
  q.quad({1, 0, 0}, {1, 0, 1}, {1, 1, 1}, {1, 1, 0}, white);  // the wall's left side, -x
  q.quad({1, 0, 0}, {1, 1, 0}, {1, 1, 1}, {1, 0, 1}, white);  // its right side, +x
  const PatchMesh mesh = mesh_scene(q.scene, {.target_patches = 2000});
  const std::vector<glm::vec3> radiosity = lit_left_dark_right(mesh);
  const FinalGather gather(mesh, radiosity, {.seed = 3});
  // The chart's side: where its faces' centres lie (the wall's sides by their normals).
  const auto side = [](const Scene& scene, const Chart& c) {
    int left = 0, right = 0;
    for (uint32_t t : c.triangles) {
      const Triangle& tri = scene.triangles[t];
      const glm::vec3 centre = (tri.p[0] + tri.p[1] + tri.p[2]) / 3.0f;
      const float nx = glm::cross(tri.p[1] - tri.p[0], tri.p[2] - tri.p[0]).x;
      const bool l = std::abs(centre.x - 1.0f) < 1e-6f ? nx < 0 : centre.x < 1.0f;
      (l ? left : right)++;
    }
    return left > 0 && right > 0 ? 0 : left > 0 ? -1 : 1;
  };
  {  // As the faces come: the floor's chart spans both rooms, and the dark side of it takes light.
    const Atlas atlas = make_atlas(q.scene, {.texel_size = 0.05, .gutter = 1});
    const Chart& floor = atlas.charts[atlas.chart_of[0]];
    EXPECT_EQ(side(q.scene, floor), 0);
    const Lightmap m = bake_lightmap(q.scene, atlas, gather, 16);
    float leaked = 0;
    for (int y = floor.y; y < floor.y + floor.height; ++y)
      for (int x = floor.x; x < floor.x + floor.width; ++x) {
        const glm::dvec3 p = floor.origin + floor.u * ((x - floor.x - 0.5) * atlas.texel_size) +
                             floor.v * ((y - floor.y - 0.5) * atlas.texel_size);  // the texel's centre
        if (p.x > 1.0 && p.x < 1.0 + atlas.texel_size) leaked = std::max(leaked, m.combined.at(x, y).x);
      }
    EXPECT_GT(leaked, 0.0f) << "the uncut floor's texels beside the wall took no light: this test shows nothing";
  }
  const Scene cut = cut_at_contacts(q.scene);
  EXPECT_GT(cut.triangles.size(), q.scene.triangles.size());
  const Atlas atlas = make_atlas(cut, {.texel_size = 0.05, .gutter = 1});
  const Lightmap m = bake_lightmap(cut, atlas, gather, 16);
  int lit = 0, dark = 0;
  for (const Chart& c : atlas.charts) {
    const int s = side(cut, c);
    ASSERT_NE(s, 0) << "a chart spans the wall";
    for (int y = c.y; y < c.y + c.height; ++y)
      for (int x = c.x; x < c.x + c.width; ++x) {
        const glm::vec3 v = m.combined.at(x, y);
        if (s > 0) {
          EXPECT_EQ(v, glm::vec3(0.0f)) << "light in the dark room at texel " << x << ", " << y;
          ++dark;
        } else if (m.coverage[static_cast<std::size_t>(y) * atlas.width + x] == 1.0f) {
          EXPECT_GT(v.x, 0.0f) << "a texel of the lit room at " << x << ", " << y;
          ++lit;
        }
      }
  }
  EXPECT_GT(lit, 1000);
  EXPECT_GT(dark, 1000);
}

// The rest of the leak suite: a room [0, 2] x [0, 1] x [0, 1] lit by its wall x = 0 (the lamp,
// facing +x), with a free-standing zero-thickness panel at x = 1 (two one-sided planes back to
// back, its front facing the lamp) and a rug lying on the floor at zero gap (a plane at z = 0,
// facing up, over x 1.3..1.7, y 0.3..0.7). The solution gives B = 1 to the lamp and the panel's
// front and 0 to everything else. No direct light can reach the panel's back: the lamp faces +x
// and the back faces +x too (no direction leaves it towards x = 0). So each of its texels has
// exactly no direct light, with all its samples kept (a sample taken on the front side of the
// same place, or a shadow ray through the panel, would bring some). Its indirect light is not 0:
// a gather ray that lands close by on the floor traces the floor's own light from the lamp. The
// rug, an object of its own, lies on top of the floor (the later face at one place: DESIGN.md,
// coincident faces): its texels keep their samples and are lit, and the floor's texels wholly
// under it take no sample (coverage 0; they are filled from their chart, and never seen).
TEST(Bake, AFreeStandingPanelsBackTakesNoDirectLightAndTheFloorUnderARugNoSample) {
  QuadScene q;
  const uint32_t white = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
  const uint32_t lamp = q.material(glm::vec3(0.5f), glm::vec3(2.0f));
  q.quad({0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {0, 1, 0}, white);  // floor, +z
  q.quad({0, 0, 1}, {0, 1, 1}, {2, 1, 1}, {2, 0, 1}, white);  // ceiling, -z
  q.quad({0, 0, 0}, {0, 0, 1}, {2, 0, 1}, {2, 0, 0}, white);  // y = 0, +y
  q.quad({0, 1, 0}, {2, 1, 0}, {2, 1, 1}, {0, 1, 1}, white);  // y = 1, -y
  q.quad({0, 0, 0}, {0, 1, 0}, {0, 1, 1}, {0, 0, 1}, lamp);   // x = 0, +x: the lamp
  q.quad({2, 0, 0}, {2, 0, 1}, {2, 1, 1}, {2, 1, 0}, white);  // x = 2, -x
  const float lo = 0.2f, hi = 0.8f;
  q.quad({1, lo, lo}, {1, lo, hi}, {1, hi, hi}, {1, hi, lo}, white);  // the panel's front, -x
  q.quad({1, lo, lo}, {1, hi, lo}, {1, hi, hi}, {1, lo, hi}, white);  // its back, +x
  const float rx0 = 1.3f, rx1 = 1.7f, ry0 = 0.3f, ry1 = 0.7f;
  q.quad({rx0, ry0, 0}, {rx1, ry0, 0}, {rx1, ry1, 0}, {rx0, ry1, 0}, white);  // the rug, +z
  q.scene.objects.push_back("rug");  // an object of its own, as modellers make one
  for (std::size_t t = q.scene.triangles.size() - 2; t < q.scene.triangles.size(); ++t) q.scene.triangles[t].object = 1;
  const Scene cut = cut_at_contacts(q.scene);
  const PatchMesh mesh = mesh_scene(cut, {.target_patches = 2000});
  std::vector<glm::vec3> radiosity(mesh.size(), glm::vec3(0.0f));
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const glm::vec3 c = (mesh.vertices[mesh.patches[j][0]] + mesh.vertices[mesh.patches[j][1]] + mesh.vertices[mesh.patches[j][2]]) / 3.0f;
    const bool front = std::abs(c.x - 1.0f) < 1e-6f && mesh.normal[j].x < 0;
    if (mesh.emits(j) || front) radiosity[j] = glm::vec3(1.0f) + mesh.emission(j);
  }
  const FinalGather gather(mesh, radiosity, {.seed = 5});
  const Atlas atlas = make_atlas(cut, {.texel_size = 0.025, .gutter = 1});
  const Lightmap m = bake_lightmap(cut, atlas, gather, 16);
  // A texel's four corners on its chart's plane.
  const auto corners = [&](const Chart& c, int x, int y) {
    std::array<glm::dvec3, 4> p;
    for (int k = 0; k < 4; ++k)
      p[static_cast<std::size_t>(k)] =
          c.origin + c.u * ((x - c.x - 1 + (k & 1)) * atlas.texel_size) + c.v * ((y - c.y - 1 + (k >> 1)) * atlas.texel_size);
    return p;
  };
  int back = 0, rug = 0, under = 0;
  for (const Chart& c : atlas.charts) {
    const bool panel_back = std::abs(c.origin.x - 1.0) < 1e-6 && c.normal.x > 0.5;
    const bool floor = std::abs(c.origin.z) < 1e-6 && c.normal.z > 0.5;
    for (int y = c.y + 1; y < c.y + c.height - 1; ++y)
      for (int x = c.x + 1; x < c.x + c.width - 1; ++x) {
        const auto p = corners(c, x, y);
        const float coverage = m.coverage[static_cast<std::size_t>(y) * atlas.width + x];
        const glm::vec3 v = m.combined.at(x, y);
        const auto in_panel = [&](const glm::dvec3& q) { return q.y >= lo && q.y <= hi && q.z >= lo && q.z <= hi; };
        if (panel_back && std::all_of(p.begin(), p.end(), in_panel)) {
          EXPECT_EQ(m.direct.at(x, y), glm::vec3(0.0f)) << "direct light on the panel's back at texel " << x << ", " << y;
          EXPECT_EQ(coverage, 1.0f) << x << ", " << y;
          ++back;
        }
        if (!floor) continue;
        const auto in_rug = [&](const glm::dvec3& q) { return q.x > rx0 && q.x < rx1 && q.y > ry0 && q.y < ry1; };
        if (!std::all_of(p.begin(), p.end(), in_rug)) continue;
        bool is_rug = true;  // the rug's chart or the floor's: the rug's faces lie within its square
        for (uint32_t t : c.triangles)
          for (const glm::vec3& v3 : cut.triangles[t].p) is_rug = is_rug && v3.x >= rx0 - 1e-6f && v3.x <= rx1 + 1e-6f && v3.y >= ry0 - 1e-6f && v3.y <= ry1 + 1e-6f;
        if (is_rug) {
          EXPECT_GT(v.x, 0.0f) << "a rug texel unlit at " << x << ", " << y;
          EXPECT_EQ(coverage, 1.0f) << x << ", " << y;
          ++rug;
        } else {
          EXPECT_EQ(coverage, 0.0f) << "a sample on the floor under the rug at texel " << x << ", " << y;
          ++under;
        }
      }
  }
  EXPECT_GT(back, 300);
  EXPECT_GT(rug, 100);
  EXPECT_GT(under, 100);
}

}  // namespace
}  // namespace sirad
