// sirad tests: the lightmap atlas (scene/atlas.h): one chart per flat (within 2 degrees)
// connected surface of an object, charts that never overlap (gutters included), every corner's
// UV inside its chart, one texel density everywhere (a projection onto the chart's plane: a
// triangle's texels are its area times its cosine to that plane over texel_size^2, to float
// rounding), the least rectangle for a turned wall, a budget kept, sizes refused; and the file's
// own lightmap UV set kept as it is, with sirad's charts below it for the faces it does not place.
#include <cmath>
#include <algorithm>
#include <cstring>
#include <set>
#include <numbers>
#include <string>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include <tiny_gltf.h>

#include "scene/atlas.h"
#include "scene/gltf.h"
#include "tests/cube_net.h"
#include "util/error.h"

namespace sirad {
namespace {

void quad(Scene& s, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, uint32_t object = 0) {
  s.triangles.push_back({.p = {a, b, c}, .object = object});
  s.triangles.push_back({.p = {a, c, d}, .object = object});
}

// The inside of a unit cube: six faces of two triangles each, in one object.
Scene cube() {
  Scene s;
  s.name = "cube";
  s.materials = {Material{"white", glm::vec3(0.5f), glm::vec3(0.0f)}};
  const glm::vec3 p[8] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  quad(s, p[0], p[1], p[2], p[3]);
  quad(s, p[4], p[7], p[6], p[5]);
  quad(s, p[0], p[4], p[5], p[1]);
  quad(s, p[3], p[2], p[6], p[7]);
  quad(s, p[0], p[3], p[7], p[4]);
  quad(s, p[1], p[5], p[6], p[2]);
  return s;
}

double area3(const Triangle& t) { return 0.5 * glm::length(glm::cross(glm::dvec3(t.p[1] - t.p[0]), glm::dvec3(t.p[2] - t.p[0]))); }

// What every atlas must be: rectangles inside the atlas and apart; each triangle's UVs inside its
// chart's rectangle less the gutter; its area in texels its area, projected onto the chart's
// plane, over texel_size^2.
void expect_sound(const Scene& s, const Atlas& a) {
  ASSERT_EQ(a.uv.size(), s.triangles.size());
  for (std::size_t i = 0; i < a.charts.size(); ++i) {
    const Chart& c = a.charts[i];
    EXPECT_TRUE(c.x >= 0 && c.y >= 0 && c.x + c.width <= a.width && c.y + c.height <= a.height) << i;
    for (std::size_t j = 0; j < i; ++j) {
      const Chart& d = a.charts[j];
      const bool apart = c.x + c.width <= d.x || d.x + d.width <= c.x || c.y + c.height <= d.y || d.y + d.height <= c.y;
      EXPECT_TRUE(apart) << "charts " << i << " and " << j << " overlap";
    }
  }
  for (std::size_t t = 0; t < s.triangles.size(); ++t) {
    const Chart& c = a.charts[a.chart_of[t]];
    double texel_area = 0;
    std::array<glm::dvec2, 3> q{};
    for (int k = 0; k < 3; ++k) {
      q[static_cast<std::size_t>(k)] = {a.uv[t][static_cast<std::size_t>(k)].x * double(a.width), a.uv[t][static_cast<std::size_t>(k)].y * double(a.height)};
      const glm::dvec2& p = q[static_cast<std::size_t>(k)];
      // Within the chart's rectangle less its gutter (a float's rounding of the UV allowed).
      EXPECT_GE(p.x, c.x + a.gutter - 1e-3) << t;
      EXPECT_LE(p.x, c.x + c.width - a.gutter + 1e-3) << t;
      EXPECT_GE(p.y, c.y + a.gutter - 1e-3) << t;
      EXPECT_LE(p.y, c.y + c.height - a.gutter + 1e-3) << t;
    }
    texel_area = 0.5 * std::abs((q[1].x - q[0].x) * (q[2].y - q[0].y) - (q[1].y - q[0].y) * (q[2].x - q[0].x));
    // UVs are floats: a corner's place is exact to about 1e-7 of the atlas's side.
    const Triangle& tri = s.triangles[t];
    const glm::dvec3 n = glm::normalize(glm::cross(glm::dvec3(tri.p[1] - tri.p[0]), glm::dvec3(tri.p[2] - tri.p[0])));
    const double expect = area3(tri) * std::abs(glm::dot(n, c.normal)) / (a.texel_size * a.texel_size);
    EXPECT_NEAR(texel_area, expect, 1e-5 * std::max(a.width, a.height) * std::sqrt(expect) + 1e-6 * expect) << t;
  }
}

// A cube's six faces are six charts of two triangles each, each a square of side / texel texels.
TEST(Atlas, EachFlatConnectedSurfaceIsOneChart) {
  const Scene s = cube();
  const Atlas a = make_atlas(s, {.texel_size = 0.1, .gutter = 2});
  ASSERT_EQ(a.charts.size(), 6u);
  for (const Chart& c : a.charts) {
    EXPECT_EQ(c.triangles.size(), 2u);
    EXPECT_EQ(c.width, 10 + 4);
    EXPECT_EQ(c.height, 10 + 4);
  }
  EXPECT_EQ(a.texel_size, 0.1);
  expect_sound(s, a);
  EXPECT_EQ(a.width % 4, 0);
  EXPECT_EQ(a.height % 4, 0);
}

// Coplanar faces of two objects, or two flat faces meeting at an edge at an angle beyond 2
// degrees (a fold of 3), are separate charts; a face cut by a door (an L of three quads sharing
// whole edges, as Blender triangulates an n-gon) is one, and so are faces folded by 0.1 and 1.9
// degrees (a quad not quite in one plane).
TEST(Atlas, ChartsFollowObjectsAndPlanes) {
  Scene s;
  s.name = "walls";
  s.materials = {Material{"white", glm::vec3(0.5f), glm::vec3(0.0f)}};
  quad(s, {0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, 0);
  quad(s, {1, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}, 1);  // the same plane, another object
  quad(s, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}, 2);  // an L: three quads in one plane
  quad(s, {1, 0, 1}, {2, 0, 1}, {2, 1, 1}, {1, 1, 1}, 2);
  quad(s, {0, 1, 1}, {1, 1, 1}, {1, 2, 1}, {0, 2, 1}, 2);
  const auto rise = [](double degrees) { return static_cast<float>(std::tan(degrees * std::numbers::pi / 180.0)); };
  for (const auto& [z, degrees] : {std::pair{5.0f, 0.1}, {7.0f, 1.9}, {9.0f, 3.0}}) {  // folded along x = 1
    const uint32_t object = 3 + static_cast<uint32_t>(z);
    quad(s, {0, 0, z}, {1, 0, z}, {1, 1, z}, {0, 1, z}, object);
    quad(s, {1, 0, z}, {2, 0, z + rise(degrees)}, {2, 1, z + rise(degrees)}, {1, 1, z}, object);
  }
  const Atlas a = make_atlas(s, {.texel_size = 0.05});
  ASSERT_EQ(a.charts.size(), 7u);
  EXPECT_EQ(a.chart_of[0], a.chart_of[1]);
  EXPECT_NE(a.chart_of[0], a.chart_of[2]);
  EXPECT_EQ(a.chart_of[4], a.chart_of[6]);
  EXPECT_EQ(a.chart_of[4], a.chart_of[8]);
  EXPECT_EQ(a.chart_of[10], a.chart_of[12]);  // 0.1 degrees
  EXPECT_EQ(a.chart_of[14], a.chart_of[16]);  // 1.9
  EXPECT_NE(a.chart_of[18], a.chart_of[20]);  // 3
  expect_sound(s, a);
}

// A curved strip (a quarter of a cylinder of 60 facets, 1.5 degrees each) is cut into charts
// whose faces all lie within 2 degrees of their chart's first face: the bound does not grow
// along the curve, so no chart spans more than three facets, and each chart is a run of
// neighbouring facets.
TEST(Atlas, ACurvedSurfaceIsNotFlattenedIntoOneChart) {
  Scene s;
  s.name = "curve";
  s.materials = {Material{"white", glm::vec3(0.5f), glm::vec3(0.0f)}};
  constexpr int kFacets = 60;
  const auto at = [](int i, float y) {
    const double a = 0.5 * std::numbers::pi * i / kFacets;
    return glm::vec3(static_cast<float>(std::cos(a)), y, static_cast<float>(std::sin(a)));
  };
  for (int i = 0; i < kFacets; ++i) quad(s, at(i, 0), at(i, 1), at(i + 1, 1), at(i + 1, 0));
  const Atlas a = make_atlas(s, {.texel_size = 0.01});
  EXPECT_GE(a.charts.size(), static_cast<std::size_t>(kFacets / 3));
  EXPECT_LT(a.charts.size(), static_cast<std::size_t>(kFacets));
  for (const Chart& c : a.charts) {
    EXPECT_LE(c.triangles.size(), 6u);
    const glm::dvec3 first = glm::normalize(glm::cross(glm::dvec3(s.triangles[c.triangles[0]].p[1] - s.triangles[c.triangles[0]].p[0]),
                                                       glm::dvec3(s.triangles[c.triangles[0]].p[2] - s.triangles[c.triangles[0]].p[0])));
    for (uint32_t t : c.triangles) {
      const Triangle& tri = s.triangles[t];
      const glm::dvec3 n = glm::normalize(glm::cross(glm::dvec3(tri.p[1] - tri.p[0]), glm::dvec3(tri.p[2] - tri.p[0])));
      EXPECT_GE(glm::dot(n, first), std::cos(2.0 * std::numbers::pi / 180.0)) << t;
      EXPECT_LE(std::abs(static_cast<int>(t / 2) - static_cast<int>(c.triangles[0] / 2)), 2) << t;
    }
  }
  expect_sound(s, a);
}

// A floor (4 x 2, one quad, facing +z) with a box wall 0.2 thick standing across it at x = 1.9 to
// 2.1 (its sides and top, facing out): cut at the contacts, the floor's pieces cover its area
// exactly, keep its material, object and line, and none lies on both sides of a wall face's
// foot; the atlas makes the floor left of the wall, under it and right of it charts of their own.
TEST(Atlas, FacesAreCutAtTheFeetOfWhatStandsOnThem) {
  Scene s;
  s.name = "floor";
  s.materials = {Material{"white", glm::vec3(0.5f), glm::vec3(0.0f)}};
  quad(s, {0, 0, 0}, {4, 0, 0}, {4, 2, 0}, {0, 2, 0}, 0);
  s.triangles[0].source_line = s.triangles[1].source_line = 7;
  quad(s, {1.9f, 0, 0}, {1.9f, 0, 1}, {1.9f, 2, 1}, {1.9f, 2, 0}, 1);  // -x
  quad(s, {2.1f, 0, 0}, {2.1f, 2, 0}, {2.1f, 2, 1}, {2.1f, 0, 1}, 1);  // +x
  quad(s, {1.9f, 0, 1}, {2.1f, 0, 1}, {2.1f, 2, 1}, {1.9f, 2, 1}, 1);  // top
  const Scene cut = cut_at_contacts(s);
  double floor_area = 0;
  int left = 0, under = 0, right = 0;
  for (const Triangle& t : cut.triangles) {
    if (t.object != 0) continue;
    EXPECT_EQ(t.source_line, 7u);
    EXPECT_EQ(t.material, 0u);
    floor_area += area3(t);
    double lo = INFINITY, hi = -INFINITY;
    for (const glm::vec3& p : t.p) lo = std::min(lo, double(p.x)), hi = std::max(hi, double(p.x));
    const bool l = hi <= 1.9 + 1e-6, u = lo >= 1.9 - 1e-6 && hi <= 2.1 + 1e-6, r = lo >= 2.1 - 1e-6;
    EXPECT_TRUE(l || u || r) << "a piece from x = " << lo << " to " << hi;
    left += l, under += u && !l && !r, right += r;
  }
  EXPECT_NEAR(floor_area, 8.0, 1e-5);
  EXPECT_GT(left, 0);
  EXPECT_GT(under, 0);
  EXPECT_GT(right, 0);
  const Atlas a = make_atlas(cut, {.texel_size = 0.05});
  for (std::size_t i = 0; i < cut.triangles.size(); ++i)
    for (std::size_t j = 0; j < cut.triangles.size(); ++j) {
      if (cut.triangles[i].object != 0 || cut.triangles[j].object != 0 || a.chart_of[i] != a.chart_of[j]) continue;
      const auto mid = [&](std::size_t k) { return (cut.triangles[k].p[0].x + cut.triangles[k].p[1].x + cut.triangles[k].p[2].x) / 3; };
      EXPECT_EQ(mid(i) < 1.9f, mid(j) < 1.9f) << i << " " << j;
      EXPECT_EQ(mid(i) > 2.1f, mid(j) > 2.1f) << i << " " << j;
    }
  expect_sound(cut, a);
}

// A wall turned 30 degrees about the vertical takes the texels of one on the axes: its chart is
// turned to the wall's own rectangle (4 x 2.5 m at 0.05: 80 x 50 texels and the gutters), not
// to its bounding box in the scene's axes.
TEST(Atlas, ATurnedWallTakesItsOwnRectangle) {
  Scene s;
  s.name = "turned";
  s.materials = {Material{"white", glm::vec3(0.5f), glm::vec3(0.0f)}};
  const double t = 30.0 * std::numbers::pi / 180.0;
  const glm::vec3 along(static_cast<float>(4 * std::cos(t)), static_cast<float>(4 * std::sin(t)), 0.0f);
  const glm::vec3 up(0.0f, 0.0f, 2.5f);
  const glm::vec3 o(0.3f, -0.2f, 0.0f);
  quad(s, o, o + along, o + along + up, o + up);
  const Atlas a = make_atlas(s, {.texel_size = 0.05, .gutter = 1});
  ASSERT_EQ(a.charts.size(), 1u);
  const Chart& c = a.charts[0];
  EXPECT_EQ(std::min(c.width, c.height), 50 + 2);
  EXPECT_EQ(std::max(c.width, c.height), 80 + 2);
  expect_sound(s, a);
}

// From a budget: the charts cover about that many texels (the texel size is the surface's over
// the budget; each chart rounds up by less than a texel a side); with a largest side too small
// for it, the texels grow until the atlas fits. A texel size that needs more is refused, and
// options out of range are, each naming what.
TEST(Atlas, ABudgetIsKeptAndSizesBeyondTheLimitsAreRefused) {
  const Scene s = cube();
  const Atlas a = make_atlas(s, {.texel_budget = 60000, .gutter = 0});
  double covered = 0;
  for (const Chart& c : a.charts) covered += double(c.width) * c.height;
  EXPECT_NEAR(a.texel_size, std::sqrt(6.0 / 60000), 1e-12);
  EXPECT_GE(covered, 60000);
  EXPECT_LE(covered, 60000 + 6 * (2 * 100 + 1));  // each square of 100 texels a side rounded up by under one
  expect_sound(s, a);
  const Atlas small = make_atlas(s, {.texel_budget = 60000, .max_side = 64});
  EXPECT_LE(std::max(small.width, small.height), 64);
  EXPECT_GT(small.texel_size, a.texel_size);
  expect_sound(s, small);
  auto refused = [&](const AtlasOptions& o, const std::string& expect) {
    try {
      make_atlas(s, o);
      ADD_FAILURE() << expect << ": accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
    }
  };
  refused({.texel_size = 1e-4}, "atlas: texels of 0.0001 make an atlas of more than 8192 x 8192 texels for cube");
  refused({.texel_size = -1}, "atlas: texel size -1 is not a finite length >= 0");
  refused({.texel_size = NAN}, "is not a finite length");
  refused({.texel_size = 0.1, .gutter = 65}, "atlas: gutter 65 is outside 0..64 texels");
  refused({.texel_size = 0.1, .max_side = 8}, "atlas: largest side 8 is outside 16..16384 texels");
  refused({.texel_budget = 0}, "atlas: texel budget 0 is outside 1..2^28");
}

// The Blender apartment as exported: its Boolean-cut walls, zero-thickness planes, turned
// furniture and lamps in an atlas of a million texels, sound, and at least half of it used.
TEST(Atlas, TheBlenderApartmentPacksSoundly) {
  const Scene s = import_gltf(std::string(SIRAD_SOURCE_DIR) + "/tests/data/blender/apartment.glb", {});
  const Atlas a = make_atlas(s, {.texel_budget = uint64_t{1} << 20});
  expect_sound(s, a);
  EXPECT_LT(a.charts.size(), s.triangles.size());
  EXPECT_GT(a.fill(), 0.5) << a.width << " x " << a.height << ", " << a.charts.size() << " charts";
  for (const Chart& c : a.charts)
    for (uint32_t t : c.triangles) EXPECT_EQ(s.triangles[t].object, s.triangles[c.triangles[0]].object);
}

// The cube with its lightmap UV as a net (tests/cube_net.h): its atlas is the file's layout as it
// is. Every corner keeps its UV; the net is one chart (not flat); the texel size is the one
// asked for (the net's faces are 0.25 in UV, 1 on the surface: 200 texels at 0.02 are 50 a face);
// a texel is the chart's where the net covers it or within the gutter of it, and no chart's
// beyond. sirad's own layout on request.
TEST(Atlas, TheFilesLightmapUvIsKept) {
  Scene s = cube();
  test::give_cube_net_uv(s);
  ASSERT_EQ(s.uv_maps.size(), 12u);
  const Atlas a = make_atlas(s, {.texel_size = 0.02, .gutter = 1});
  EXPECT_EQ(a.file_width, 200);
  EXPECT_EQ(a.file_height, 200);
  EXPECT_EQ(a.width, 200);
  EXPECT_EQ(a.height, 200);
  EXPECT_NEAR(a.texel_size, 0.02, 1e-12);
  ASSERT_EQ(a.charts.size(), 1u);
  EXPECT_FALSE(a.charts[0].flat);
  EXPECT_EQ(a.shared_texels, 0u);
  EXPECT_EQ(a.face_texels, 6u * 50 * 50);
  for (std::size_t t = 0; t < s.triangles.size(); ++t)
    for (std::size_t k = 0; k < 3; ++k) {
      const glm::dvec2 want = s.uv_maps[s.triangles[t].uv_map].at(glm::dvec3(s.triangles[t].p[k]));
      EXPECT_NEAR(a.uv[t][k].x, want.x, 1e-6) << t;
      EXPECT_NEAR(a.uv[t][k].y, want.y, 1e-6) << t;
    }
  const auto owner = [&](int x, int y) { return a.owner[static_cast<std::size_t>(y) * a.width + x]; };
  EXPECT_EQ(owner(10, 10), 0u);         // the floor
  EXPECT_EQ(owner(49, 10), 0u);         // its last column
  EXPECT_EQ(owner(50, 10), 0u);         // the gutter beside it
  EXPECT_EQ(owner(51, 10), kNoChart);   // beyond
  EXPECT_EQ(owner(199, 60), 0u);        // the x = 0 wall at the square's right edge
  EXPECT_EQ(owner(150, 10), kNoChart);  // no face there
  EXPECT_EQ(owner(10, 160), kNoChart);  // below the ceiling

  const Atlas own = make_atlas(s, {.texel_size = 0.02, .gutter = 1, .file_layout = false});
  EXPECT_EQ(own.file_width, 0);
  EXPECT_EQ(own.charts.size(), 6u);
  expect_sound(s, own);
}

// Two islands that touch inside texel (0, 0) of an 8-texel square: the first covers its left
// 49 % (8 of its 16 points), the second the rest and its centre (8 points as well). The texel is
// the second's, as a baker that rasterises texel centres (Cycles) has it.
TEST(Atlas, ATexelIsTheIslandsThatHoldsItsCentre) {
  Scene s;
  s.name = "two islands";
  s.materials = {Material{"white", glm::vec3(0.5f), glm::vec3(0.0f)}};
  const auto island = [&](float x0, double u0, double u1) {
    quad(s, {x0, 0, 0}, {x0 + 1, 0, 0}, {x0 + 1, 1, 0}, {x0, 1, 0});
    for (std::size_t t = s.triangles.size() - 2; t < s.triangles.size(); ++t) {
      std::array<glm::dvec3, 3> p;
      std::array<glm::dvec2, 3> uv;
      for (std::size_t k = 0; k < 3; ++k) {
        p[k] = glm::dvec3(s.triangles[t].p[k]);
        uv[k] = {u0 + (p[k].x - x0) * (u1 - u0), p[k].y / 8};
      }
      UvMap map;
      ASSERT_TRUE(make_uv_map(p, uv, map));
      s.triangles[t].uv_map = static_cast<uint32_t>(s.uv_maps.size());
      s.uv_maps.push_back(map);
    }
  };
  island(0, 0, 0.49 / 8);
  island(3, 0.49 / 8, 3.0 / 8);
  const double uv_area = 3.0 / 8 / 8;
  const Atlas a = make_atlas(s, {.texel_size = std::sqrt(2 / uv_area) / 7.9, .gutter = 0});
  ASSERT_EQ(a.file_width, 8);
  ASSERT_EQ(a.charts.size(), 2u);
  EXPECT_EQ(a.owner[0], a.chart_of[2]);  // the second island's
  EXPECT_EQ(a.owner[1], a.chart_of[2]);
  EXPECT_EQ(a.chart_of[0], 0u);
}

// An edge shared by more than 16 faces (a fan of coincident faces: a hostile file, where each
// face looking at every other would take time quadratic in their number) joins nothing: 17
// copies of a triangle are 17 charts, 16 are one.
TEST(Atlas, AnEdgeOfManyFacesJoinsNoChart) {
  for (int copies : {16, 17}) {
    Scene s;
    s.name = "fan";
    s.materials = {Material{"white", glm::vec3(0.5f), glm::vec3(0.0f)}};
    for (int i = 0; i < copies; ++i) s.triangles.push_back({.p = {glm::vec3(0, 0, 0), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0)}});
    const Atlas a = make_atlas(s, {.texel_size = 0.1, .gutter = 1});
    EXPECT_EQ(a.charts.size(), copies == 16 ? 1u : 17u) << copies;
  }
}

// Faces the file's square does not hold (the back side of a two-sided face, which shares its
// front's UV; a face whose UV leaves the square) get sirad's charts in shelves below it, at its
// texel size; the file's faces keep their UV, only squeezed by the square's share of the height.
// Islands laid over each other (the ceiling moved onto the floor in UV) are counted.
TEST(Atlas, FacesTheFilesSquareDoesNotHoldGoBelowIt) {
  Scene s = cube();
  test::give_cube_net_uv(s);
  s.triangles[0].back = s.triangles[1].back = true;                       // the floor
  s.uv_maps[s.triangles[2].uv_map].uv0.x += 2;                            // the ceiling's first half
  const Atlas a = make_atlas(s, {.texel_size = 0.02, .gutter = 1});
  EXPECT_EQ(a.file_width, 200);
  EXPECT_EQ(a.width, 200);
  ASSERT_GE(a.height, 200 + 50);
  ASSERT_EQ(a.charts.size(), 3u);  // the floor, the ceiling's half, the rest in the file's layout
  for (uint32_t t : {0u, 1u, 2u}) {
    EXPECT_TRUE(a.charts[a.chart_of[t]].flat);
    for (std::size_t k = 0; k < 3; ++k) EXPECT_GE(a.uv[t][k].y * a.height, 200.0 - 1e-3) << t;
  }
  for (std::size_t t = 3; t < s.triangles.size(); ++t)
    for (std::size_t k = 0; k < 3; ++k) {
      const glm::dvec2 want = s.uv_maps[s.triangles[t].uv_map].at(glm::dvec3(s.triangles[t].p[k]));
      EXPECT_NEAR(a.uv[t][k].x, want.x, 1e-6) << t;
      EXPECT_NEAR(a.uv[t][k].y, want.y * 200 / a.height, 1e-6) << t;
    }
  for (const Chart& c : a.charts)
    if (c.flat) EXPECT_NEAR(c.texel, 0.02, 1e-12);

  Scene over = cube();
  test::give_cube_net_uv(over);
  for (uint32_t t : {2u, 3u}) over.uv_maps[over.triangles[t].uv_map].uv0.y -= 0.5;  // the ceiling onto the floor
  const Atlas b = make_atlas(over, {.texel_size = 0.02, .gutter = 1});
  EXPECT_EQ(b.charts.size(), 2u);
  EXPECT_GE(b.shared_texels, 48u * 48);
  EXPECT_LE(b.shared_texels, 50u * 50);

  // Every face laid over the whole square (a hostile file): its faces' bounds hold 12 times the
  // square: refused before any is rasterised, naming the way out.
  Scene all = cube();
  for (Triangle& t : all.triangles) {
    UvMap map;
    ASSERT_TRUE(make_uv_map({glm::dvec3(t.p[0]), glm::dvec3(t.p[1]), glm::dvec3(t.p[2])}, {glm::dvec2(0, 0), glm::dvec2(1, 0), glm::dvec2(0, 1)}, map));
    t.uv_map = static_cast<uint32_t>(all.uv_maps.size());
    all.uv_maps.push_back(map);
  }
  try {
    make_atlas(all, {.texel_size = 0.02, .gutter = 1});
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--own-atlas"), std::string::npos) << e.what();
  }
}

// The apartment with a lightmap UV set made by Blender's Lightmap Pack (every face an island,
// tests/data/blender/add_lightmap_uv.py): its atlas is the file's layout. Each face that comes
// through the import whole has the file's own TEXCOORD_1 at its corners (read here from the glb
// by tinygltf); no islands overlap; the back
// sides that take part get sirad's charts below the square; each quad's diagonal is a seam.
TEST(Atlas, BlendersLightmapPackIsTheLayout) {
  const std::string path = std::string(SIRAD_SOURCE_DIR) + "/tests/data/blender/apartment-uv2.glb";
  const Scene s = import_gltf(path, {});
  const Atlas a = make_atlas(s, {.texel_budget = uint64_t{1} << 18});
  ASSERT_GT(a.file_width, 0);
  EXPECT_EQ(a.shared_texels, 0u);
  EXPECT_GT(a.seams.size(), 100u);
  // The file's triangles by their TEXCOORD_1 (Lightmap Pack's islands do not overlap, so a
  // triangle's three UVs name it), read by tinygltf; each corner rounded to 1e-5.
  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &err, &warn, path)) << err;
  using Key = std::array<long, 6>;
  const auto key_of = [](std::array<glm::dvec2, 3> uv) {
    std::sort(uv.begin(), uv.end(), [](const glm::dvec2& p, const glm::dvec2& q) { return p.x < q.x || (p.x == q.x && p.y < q.y); });
    Key k;
    for (std::size_t c = 0; c < 3; ++c) k[2 * c] = std::lround(uv[c].x * 1e5), k[2 * c + 1] = std::lround(uv[c].y * 1e5);
    return k;
  };
  std::set<Key> file;
  for (const tinygltf::Mesh& mesh : m.meshes)
    for (const tinygltf::Primitive& prim : mesh.primitives) {
      const tinygltf::Accessor& ua = m.accessors[static_cast<std::size_t>(prim.attributes.at("TEXCOORD_1"))];
      const tinygltf::BufferView& uv_view = m.bufferViews[static_cast<std::size_t>(ua.bufferView)];
      ASSERT_EQ(ua.componentType, TINYGLTF_COMPONENT_TYPE_FLOAT);
      const unsigned char* ub = m.buffers[static_cast<std::size_t>(uv_view.buffer)].data.data() + uv_view.byteOffset + ua.byteOffset;
      const std::size_t stride = static_cast<std::size_t>(ua.ByteStride(uv_view));
      const tinygltf::Accessor& ia = m.accessors[static_cast<std::size_t>(prim.indices)];
      const tinygltf::BufferView& iv = m.bufferViews[static_cast<std::size_t>(ia.bufferView)];
      const unsigned char* ib = m.buffers[static_cast<std::size_t>(iv.buffer)].data.data() + iv.byteOffset + ia.byteOffset;
      for (std::size_t i = 0; i + 2 < ia.count; i += 3) {
        std::array<glm::dvec2, 3> uv;
        for (std::size_t k = 0; k < 3; ++k) {
          uint32_t v = 0;
          if (ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) {
            uint16_t h;
            std::memcpy(&h, ib + (i + k) * 2, 2);
            v = h;
          } else {
            std::memcpy(&v, ib + (i + k) * 4, 4);
          }
          float f[2];
          std::memcpy(f, ub + v * stride, sizeof f);
          uv[k] = {f[0], f[1]};
        }
        file.insert(key_of(uv));
      }
    }
  std::size_t found = 0, fronts = 0;
  for (std::size_t t = 0; t < s.triangles.size(); ++t) {
    if (s.triangles[t].back) continue;
    ++fronts;
    std::array<glm::dvec2, 3> uv;
    for (std::size_t k = 0; k < 3; ++k)
      uv[k] = {double(a.uv[t][k].x) * a.width / a.file_width, double(a.uv[t][k].y) * a.height / a.file_height};
    found += file.count(key_of(uv));  // a piece cut by the import (gaps) is no triangle of the file
  }
  EXPECT_GT(found, fronts / 2) << found << " of " << fronts << " faces";
  bool backs = false;
  for (const Triangle& t : s.triangles) backs = backs || t.back;
  EXPECT_EQ(a.height > a.file_height, backs);
}

}  // namespace
}  // namespace sirad
