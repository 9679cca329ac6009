// sirad tests: coincident and touching faces, the geometry of the scenes users bring (DESIGN.md
// section 1, "Coincident faces"). Zero-thickness walls made of two one-sided faces back to back,
// triangulated differently, axis-aligned and at an oblique angle; a free-standing zero-thickness
// panel in a closed room; a rug laid on a floor at zero gap and 2 mm above it; walls standing on
// a floor in the middle of its faces and walls cut into strips whose vertices fall on the middle
// of their neighbours' edges (T-junctions). Each is compared per region (the room lit only
// through a doorway, the patches under a rug, each side of a panel) against the reference solver
// (solver/reference.h), for the bundle transport (tests/agreement.h) and for the first shot.
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <gtest/gtest.h>

#include "engine/bundle_cl.h"
#include "engine/shot.h"
#include "scene/mesh.h"
#include "scene/rays.h"
#include "scene/scene.h"
#include "solver/reference.h"
#include "tests/agreement.h"
#include "tests/coincident_scenes.h"
#include "tests/test_util.h"

namespace sirad {
namespace {

using glm::dvec3;

using test::ObjBuilder;
using test::oblique;
using test::two_rooms;
using test::panel_room;
using test::rug_room;

// Regions of a meshed scene by where a patch is in the scene's own (unrotated) frame.
using Where = std::function<bool(const PatchMesh&, std::size_t, const dvec3& centre, const dvec3& normal)>;
test::Region region(const PatchMesh& mesh, const glm::dmat3& rotation, const std::string& name, const Where& where) {
  test::Region r{name, std::vector<char>(mesh.size(), 0)};
  glm::dmat3 back = glm::transpose(rotation);
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const auto& t = mesh.patches[j];
    dvec3 c = back * (dvec3(mesh.vertices[t[0]]) + dvec3(mesh.vertices[t[1]]) + dvec3(mesh.vertices[t[2]])) / 3.0;
    r.in[j] = !mesh.emits(j) && where(mesh, j, c, back * dvec3(mesh.normal[j]));
  }
  return r;
}

// Every patch of `in` has its three vertices inside the box [lo, hi] of the scene's own frame.
bool inside(const PatchMesh& mesh, std::size_t j, const glm::dmat3& rotation, dvec3 lo, dvec3 hi) {
  glm::dmat3 back = glm::transpose(rotation);
  for (uint32_t v : mesh.patches[j]) {
    dvec3 p = back * dvec3(mesh.vertices[v]);
    for (int c = 0; c < 3; ++c)
      if (p[c] < lo[c] - 1e-4 || p[c] > hi[c] + 1e-4) return false;
  }
  return true;
}

struct Solved {
  PatchMesh mesh;
  ReferenceSolution ref;
};
Solved solved(const Scene& scene, std::size_t patches) {
  Solved s{mesh_scene(scene, {.target_patches = patches}), {}};
  s.ref = solve_reference(s.mesh, {.rays_per_patch = 8192, .light_samples = 1024, .batches = 16, .seed = 41});
  return s;
}

// The bundle transport on the OpenCL device against the reference, per region: |d| < 3 SE (a
// 0.3 % false alarm per region if both are unbiased) and SE < 0.5 % / 3, so that a 0.5 % bias
// of any region would show. 16 replicates (the reference's batches) of 48 x 48 stratified
// directions: with 8 replicates, or 36 x 36, the SE of the small regions (a panel's side)
// scattered by 2x from seed to seed (measured over 5 seeds), too unreliable to test against;
// at 16 x 48 x 48 the spread over seeds matched the reported SE within 1.6x.
void expect_transport_agrees(const std::string& name, const Solved& s, const std::vector<test::Region>& regions, int m) {
  auto engine = make_cl_engine(s.mesh);
  auto result = test::transport_agreement(s.mesh, s.ref, *engine, auto_grid(s.mesh), m, regions);
  for (const auto& a : result) {
    std::printf("%s, %s: transport - reference %+.3f%% +- %.3f%% (reference mean %.5f), d / SE %+.2f\n", name.c_str(),
                a.region.c_str(), 100 * a.d, 100 * a.se, a.reference, a.d / a.se);
    EXPECT_LT(a.se, 0.005 / 3) << name << ", " << a.region << ": the comparison could not see a 0.5 % bias";
    EXPECT_LT(std::abs(a.d), 3 * a.se) << name << ", " << a.region << ": the bundles and the reference disagree";
  }
}

// The first shot's direct light (the hemicube kernel) against the reference's direct part per
// region. G = 16 independent batches of stratified shots give the shots' SE; the reference's SE
// of a region's aggregate is at most the area-weighted sum of its per-patch SEs (full
// correlation), added in quadrature. Differences are taken relative to the region's own direct
// light or, where that is less, to what it would have at the scene's mean direct radiance
// (sum_all A D / sum_all A, times the region's area), so that a region lit only through a
// doorway is held to the absolute standard of a lit one: a face lit from behind or through a
// thin wall, or a lit face dark on half its lines, is a large error in these units. Pass:
// |d| < 3 SE, SE < 1 % / 3.
// A region the reference finds unlit (nothing reaches the back of a thin wall) must be exactly
// unlit in the shots too.
void expect_direct_agrees(const std::string& name, const Solved& s, const std::vector<test::Region>& regions,
                          int per_batch) {
  auto shots = make_cl_shot_engine(s.mesh);
  const int G = 16;
  std::vector<std::vector<dvec3>> batch;
  for (int g = 0; g < G; ++g) {
    ShotSums sums = run_shots(s.mesh, *shots, 64, 17, static_cast<uint64_t>(g * per_batch),
                              static_cast<uint64_t>(per_batch), Stream::shots, true);
    for (auto& v : sums.direct) v /= static_cast<double>(sums.shots);
    batch.push_back(std::move(sums.direct));
  }
  double all = 0.0, all_area = 0.0;
  for (std::size_t j = 0; j < s.mesh.size(); ++j) {
    all += s.mesh.area[j] * (s.ref.direct[j].x + s.ref.direct[j].y + s.ref.direct[j].z);
    all_area += s.mesh.area[j];
  }
  for (const auto& r : regions) {
    double area = 0.0;
    auto agg = [&](const std::vector<dvec3>& v) {
      double sum = 0.0;
      for (std::size_t j = 0; j < s.mesh.size(); ++j)
        if (r.in[j]) sum += s.mesh.area[j] * (v[j].x + v[j].y + v[j].z);
      return sum;
    };
    for (std::size_t j = 0; j < s.mesh.size(); ++j)
      if (r.in[j]) area += s.mesh.area[j];
    std::vector<double> d;
    for (const auto& b : batch) d.push_back(agg(b));
    auto [m, sd] = test::mean_sd(d);
    double ref = agg(s.ref.direct), ref_se = agg(s.ref.direct_se), unit = std::max(ref, all / all_area * area);
    if (ref == 0.0) {
      EXPECT_EQ(m, 0.0) << name << ", " << r.name << ": lit in the shots, unlit in the reference";
      continue;
    }
    double diff = (m - ref) / unit, se = std::hypot(sd / std::sqrt(static_cast<double>(G)), ref_se) / unit;
    std::printf("%s, %s: first shot - reference direct %+.3f%% +- %.3f%% (shots %.3f%%, reference %.3f%%) of the "
                "region's or the scene's mean (region / scene mean %.3f), d / SE %+.2f\n", name.c_str(), r.name.c_str(), 100 * diff, 100 * se,
                100 * sd / std::sqrt(static_cast<double>(G)) / unit, 100 * ref_se / unit, ref / (all / all_area * area), diff / se);
    EXPECT_LT(se, 0.01 / 3) << name << ", " << r.name;
    EXPECT_LT(std::abs(diff), 3 * se) << name << ", " << r.name;
  }
}

std::vector<test::Region> room_regions(const PatchMesh& mesh, const glm::dmat3& rot, double gap) {
  return {region(mesh, rot, "room A (lit)", [](auto&, auto, const dvec3& c, auto&) { return c.x < 4.0 - 1e-3; }),
          region(mesh, rot, "room B (through the doorway)",
                 [gap](auto&, auto, const dvec3& c, auto&) { return c.x > 4.0 + gap + 1e-3; }),
          region(mesh, rot, "wall towards A", [](auto&, auto, const dvec3& c, const dvec3& n) {
            return std::abs(c.x - 4.0) < 1e-3 && n.x < -0.5;
          }),
          region(mesh, rot, "wall towards B", [gap](auto&, auto, const dvec3& c, const dvec3& n) {
            return std::abs(c.x - 4.0 - gap) < 1e-3 && n.x > 0.5;
          })};
}

// The reference treats a zero-thickness wall as the limit of a thin one: at zero gap and at a
// gap of 1 mm (far above the coincidence tolerance, 1e-5 of the scene's size) the rooms agree
// within their standard errors (the 1 mm slit itself lets through a negligible 2.5e-4 of the
// doorway's light). A ray that met the wall's two faces at one distance used to see either
// face, the back one half the time, leaving room B 16 % too dark: this fails on that reference.
TEST(Coincident, ReferenceSeesAZeroThicknessWallAsTheLimitOfAThinOne) {
  Solved zero = solved(two_rooms(0.0, glm::dmat3(1.0)), 1500), thin = solved(two_rooms(1e-3, glm::dmat3(1.0)), 1500);
  auto rz = room_regions(zero.mesh, glm::dmat3(1.0), 0.0), rt = room_regions(thin.mesh, glm::dmat3(1.0), 1e-3);
  for (std::size_t k = 0; k < 2; ++k) {
    auto mean_se = [](const Solved& s, const test::Region& r) {
      double b = 0, se = 0, a = 0;
      for (std::size_t j = 0; j < s.mesh.size(); ++j)
        if (r.in[j]) {
          b += s.mesh.area[j] * (s.ref.radiosity[j].x + s.ref.radiosity[j].y + s.ref.radiosity[j].z);
          se += s.mesh.area[j] * (s.ref.radiosity_se[j].x + s.ref.radiosity_se[j].y + s.ref.radiosity_se[j].z);
          a += s.mesh.area[j];
        }
      return std::pair{b / a, se / a};  // the SE of the mean at most the mean SE (full correlation)
    };
    auto [bz, sz] = mean_se(zero, rz[k]);
    auto [bt, st] = mean_se(thin, rt[k]);
    std::printf("%s: zero gap %.5f +- %.5f, 1 mm gap %.5f +- %.5f\n", rz[k].name.c_str(), bz, sz, bt, st);
    EXPECT_LT(std::abs(bz - bt), 3 * std::hypot(sz, st)) << rz[k].name;
  }
}

// 64 x 64 directions: at 48 x 48 (transport seeds 77/78) room B read +0.185 % +- 0.054 % on the
// floor split along the wall's foot, and +0.128 % +- 0.063 % against another reference seed
// with the same directions, but -0.071 % +- 0.072 % with other directions: the directions'
// sample, which the SE (from 16 replicates) can understate by up to 1.6x (above).
TEST(Coincident, ThinWallWithADoorway) {
  Solved s = solved(two_rooms(0.0, glm::dmat3(1.0)), 1500);
  expect_transport_agrees("two rooms", s, room_regions(s.mesh, glm::dmat3(1.0), 0.0), 64);
}

TEST(Coincident, ThinWallAtAnObliqueAngleWithTJunctions) {
  glm::dmat3 rot = oblique(37.0);
  Solved s = solved(two_rooms(0.0, rot, 3), 1500);
  expect_transport_agrees("two rooms, oblique, T-junctions", s, room_regions(s.mesh, rot, 0.0), 48);
}

TEST(Coincident, ThinWallFirstShot) {
  glm::dmat3 rot = oblique(37.0);
  Solved s = solved(two_rooms(0.0, rot, 3), 1500);
  expect_direct_agrees("two rooms, oblique", s, room_regions(s.mesh, rot, 0.0), 512);
}

bool made_of(const PatchMesh& mesh, std::size_t j, const std::string& material) {
  return mesh.materials[mesh.material[j]].name == material;
}

std::vector<test::Region> panel_regions(const PatchMesh& mesh, const glm::dmat3& rot) {
  auto on_panel = [&mesh](std::size_t j) { return made_of(mesh, j, "panel"); };
  return {region(mesh, rot, "room", [=](auto&, std::size_t j, auto&, auto&) { return !on_panel(j); }),
          region(mesh, rot, "panel front", [=](auto&, std::size_t j, auto&, const dvec3& n) { return on_panel(j) && n.y > 0; }),
          region(mesh, rot, "panel back", [=](auto&, std::size_t j, auto&, const dvec3& n) { return on_panel(j) && n.y < 0; })};
}

TEST(Coincident, FreeStandingZeroThicknessPanel) {
  glm::dmat3 rot = oblique(61.0);
  Solved s = solved(panel_room(rot), 1500);
  auto regions = panel_regions(s.mesh, rot);
  expect_transport_agrees("panel room", s, regions, 48);
  expect_direct_agrees("panel room", s, regions, 1024);
}

// The floor patches wholly under the rug (their vertices inside its footprint), and beside it.
test::Region floor_part(const PatchMesh& mesh, const glm::dmat3& rot, bool under) {
  dvec3 lo(1.1, -1e-3, 1.3), hi(2.7, 1e-3, 2.5);
  return region(mesh, rot, under ? "floor under the rug" : "floor beside the rug", [=, &mesh](auto&, std::size_t j, auto&, auto&) {
    return made_of(mesh, j, "floor") && inside(mesh, j, rot, lo, hi) == under;
  });
}

std::vector<test::Region> rug_regions(const PatchMesh& mesh, const glm::dmat3& rot) {
  return {region(mesh, rot, "rug", [&](auto&, std::size_t j, auto&, auto&) { return made_of(mesh, j, "rug"); }),
          floor_part(mesh, rot, false),
          region(mesh, rot, "walls and ceiling", [&](auto&, std::size_t j, auto&, auto&) { return made_of(mesh, j, "wall"); })};
}

// A rug laid on the floor at zero gap: the later face is on top, whatever the rounding, so the
// floor under the rug is dark, exactly: every line crossing it meets the rug's back next (the
// transport gathers exactly 0 there; before the rule, rounding put the floor on top of about
// half of those lines), and the reference agrees; everything else agrees per region.
TEST(Coincident, RugAtZeroGapCoversTheFloor) {
  glm::dmat3 rot = oblique(23.0);
  Solved s = solved(rug_room(0.0, rot), 1500);
  test::Region under = floor_part(s.mesh, rot, true);
  std::size_t count = 0;
  for (std::size_t j = 0; j < s.mesh.size(); ++j) count += under.in[j];
  // The floor is cut along the rug's outline (scene.h cut_along_gaps), and its pieces under the
  // rug, which no light reaches, are meshed whole (Triangle::unlit): a few patches.
  ASSERT_GT(count, 0u);
  auto engine = make_cl_engine(s.mesh);
  std::vector<glm::vec4> input(s.mesh.size());
  for (std::size_t j = 0; j < s.mesh.size(); ++j) input[j] = glm::vec4(glm::vec3(s.ref.radiosity[j]), 0.0f);
  BundleResult r;
  const int grid = auto_grid(s.mesh);
  uint64_t lines = 0;
  for (uint64_t k = 0; k < 256; ++k) {
    engine->run(make_bundle(s.mesh, grid, 5, k), input, r);
    for (std::size_t j = 0; j < s.mesh.size(); ++j)
      if (under.in[j]) {
        EXPECT_EQ(r.gathered[j], glm::vec4(0.0f)) << "bundle " << k << ", patch " << j;
        lines += r.hits[j];
      }
    if (HasFailure()) break;
  }
  EXPECT_GT(lines, 1000u) << "lines did cross the floor under the rug";
  for (std::size_t j = 0; j < s.mesh.size(); ++j)
    if (under.in[j]) {
      EXPECT_EQ(s.ref.radiosity[j], dvec3(0.0)) << "reference, patch " << j;
    }
  auto shots = make_cl_shot_engine(s.mesh);
  ShotSums d = run_shots(s.mesh, *shots, 64, 3, 0, 64, Stream::shots, true);
  for (std::size_t j = 0; j < s.mesh.size(); ++j)
    if (under.in[j]) {
      EXPECT_EQ(d.direct[j], dvec3(0.0)) << "first shot, patch " << j;
    }
  auto regions = rug_regions(s.mesh, rot);
  expect_transport_agrees("rug at zero gap", s, regions, 48);
  expect_direct_agrees("rug at zero gap", s, regions, 512);
}

// 2 mm above the floor (far above the tie) the rug is a separate surface, lit from above and
// shading the floor: per region as above.
TEST(Coincident, RugTwoMillimetresAboveTheFloor) {
  glm::dmat3 rot = oblique(23.0);
  Solved s = solved(rug_room(2e-3, rot), 1500);
  expect_transport_agrees("rug 2 mm up", s, rug_regions(s.mesh, rot), 48);
}

// The rays of the final gather and the reference take the coincident-face rule's second look
// along a ray only at a face that shares a place with another facing the same way
// (RayScene::overlapped): the rug and the floor under it, and no wall, ceiling or lamp, though
// they meet at edges and corners; nor a thin wall's or a panel's two faces (they face apart)
// cut into different rectangles with T-junctions. Elsewhere the first face met, facing the ray,
// is seen: against a scene that takes the rule for every hit, random rays from inside the rooms
// see the same patch except where they meet two faces within the tie of each other (an edge or
// a contact, where either is the place: 2 x 6e-5 m bands along 0.2 m patches, under 1e-3 of
// the hits; bound 2e-3), and never the background where the rule sees a face.
TEST(Coincident, OnlyFacesSharingAPlaceTakeTheSecondLook) {
  const glm::dmat3 rot = oblique(23.0);
  struct Case {
    Scene scene;
    glm::dvec3 lo, hi;  // the room the rays start in, before the rotation
  };
  const Case cases[] = {{rug_room(0.0, rot), {0.05, 0.05, 0.05}, {3.95, 2.9, 3.95}},
                        {panel_room(rot), {0.05, 0.05, 0.05}, {3.95, 2.9, 3.95}},
                        {two_rooms(0.0, rot, 3), {0.05, 0.05, 0.05}, {7.95, 2.9, 3.95}}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.scene.name);
    const PatchMesh mesh = mesh_scene(c.scene, {.target_patches = 1500});
    const double tie = ray_offset(mesh);
    const RayScene rays(mesh, tie), rule(mesh, tie, true);
    std::size_t overlapped = 0;
    for (uint32_t j = 0; j < mesh.size(); ++j) {
      const std::string& m = mesh.materials[mesh.material[j]].name;
      const bool on_floor = m == "floor" && inside(mesh, j, rot, dvec3(1.1, -1e-3, 1.3), dvec3(2.7, 1e-3, 2.5));
      if (m == "rug" || (on_floor && c.scene.name.starts_with("rug"))) {
        EXPECT_TRUE(rays.overlapped(j)) << m << " patch " << j;
      } else if (m != "floor" || !c.scene.name.starts_with("rug")) {
        EXPECT_FALSE(rays.overlapped(j)) << m << " patch " << j;
      }
      overlapped += rays.overlapped(j);
      EXPECT_TRUE(rule.overlapped(j));
    }
    if (c.scene.name.starts_with("rug")) {
      EXPECT_GT(overlapped, 10u);
    }
    Rng rng(7, 0, 0, 0);
    constexpr int kRays = 100000;
    int differ = 0;
    for (int i = 0; i < kRays; ++i) {
      const dvec3 o = rot * (c.lo + (c.hi - c.lo) * dvec3(rng.uniform(), rng.uniform(), rng.uniform()));
      const dvec3 d = glm::normalize(dvec3(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5));
      const auto [a, ta] = rays.seen_at(o, d);
      const auto [b, tb] = rule.seen_at(o, d);
      if (a == b) continue;
      ++differ;
      EXPECT_TRUE(a >= 0 && b >= 0) << "ray " << i << ": " << a << " against the rule's " << b;
      EXPECT_NEAR(ta, tb, 2.0 * tie) << "ray " << i;
    }
    EXPECT_LE(differ, kRays * 2 / 1000);
    // The streams (a batch of rays from one origin, a batch of segments) find what the rays one
    // by one find, exactly.
    for (int b = 0; b < 200; ++b) {
      const dvec3 o = rot * (c.lo + (c.hi - c.lo) * dvec3(rng.uniform(), rng.uniform(), rng.uniform()));
      const dvec3 axis = glm::normalize(dvec3(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5));
      std::array<dvec3, 64> dirs, ends;
      for (std::size_t i = 0; i < dirs.size(); ++i) {
        const double spread = b % 2 ? 0.02 : 1.0;  // a pixel's rays, or every way
        dirs[i] = glm::normalize(axis + spread * dvec3(rng.uniform() - 0.5, rng.uniform() - 0.5, rng.uniform() - 0.5));
        ends[i] = rot * (c.lo + (c.hi - c.lo) * dvec3(rng.uniform(), rng.uniform(), rng.uniform()));
      }
      std::array<std::pair<int64_t, double>, 64> hits;
      rays.seen_at(o, dirs.data(), dirs.size(), hits.data());
      std::array<dvec3, 64> starts;
      starts.fill(o);
      std::array<bool, 64> blocked;
      rays.blocked(starts.data(), ends.data(), ends.size(), blocked.data());
      for (std::size_t i = 0; i < dirs.size(); ++i) {
        EXPECT_EQ(hits[i], rays.seen_at(o, dirs[i])) << "batch " << b << ", ray " << i;
        EXPECT_EQ(blocked[i], rays.blocked(o, ends[i])) << "batch " << b << ", segment " << i;
      }
      if (HasFailure()) break;
    }
  }
}

}  // namespace
}  // namespace sirad

namespace sirad {
namespace {

// A furnace built inside out (a cube of side 2 with its normals pointing out, E = 1, rho = 0.5)
// made two-sided: every face gets a twin facing in (DESIGN.md section 1, "Two-sided
// surfaces"). Inside, the twins are a furnace: B = 2; outside, the original faces see only the
// background: B = E = 1 exactly, in the reference and in the bundles (no line crossing an outer
// face has a front neighbour). The reference inside: as for the furnace (rounding, 1e-5,
// tests/solver/reference_test.cpp) plus the rays that meet a wall's two faces at a grazing angle,
// where float hit distances differ by about 2^-24 |x| / sin(theta) and exceed the tie for
// sin(theta) < 6e-3: the flux arriving that flat is about theta^2 / 2 = 2e-5 of it, half of
// which sees the back face first, so B inside may fall short by a few 1e-5: bound 1e-4. The
// bundles with the control variate: the bound of tests/solver/solver_test.cpp's furnace, relative RMS
// per patch < 0.0015 after 1024 bundles.
TEST(TwoSided, AnInsideOutFurnaceIsAFurnaceInside) {
  ObjBuilder o(oblique(29.0));
  o.material("glow");
  const double L = 2;
  o.quad({0, 0, 0}, {L, 0, 0}, {L, 0, L}, {0, 0, L});  // y = 0, normal -y (out)
  o.quad({0, L, 0}, {0, L, L}, {L, L, L}, {L, L, 0});  // y = L, normal +y
  o.wall_x(0, 0, L, 0, L, false);
  o.wall_x(L, 0, L, 0, L, true);
  o.quad({0, 0, 0}, {0, L, 0}, {L, L, 0}, {L, 0, 0});  // z = 0, normal -z
  o.quad({0, 0, L}, {L, 0, L}, {L, L, L}, {0, L, L});  // z = L, normal +z
  Scene scene = o.scene("inside-out furnace", "newmtl glow\nKd 0.5 0.5 0.5\nKe 1 1 1\nsirad_two_sided 1\n");
  PatchMesh mesh = mesh_scene(scene, {.target_patches = 600});
  const dvec3 centre = oblique(29.0) * dvec3(1.0);  // the cube's centre, turned with it
  auto inner = [&](std::size_t j) {  // a patch facing the centre
    dvec3 c = (dvec3(mesh.vertices[mesh.patches[j][0]]) + dvec3(mesh.vertices[mesh.patches[j][1]]) +
               dvec3(mesh.vertices[mesh.patches[j][2]])) / 3.0;
    return glm::dot(dvec3(mesh.normal[j]), centre - c) > 0.0;
  };
  ReferenceSolution ref = solve_reference(mesh, {.rays_per_patch = 256, .light_samples = 16, .batches = 2, .seed = 3});
  auto engine = make_cl_engine(mesh);
  Solver solver = test::solve(mesh, *engine, {.seed = 5}, 1024);
  auto est = solver.estimate();
  double inner_sq = 0, inner_area = 0;
  std::size_t inner_count = 0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    if (inner(j)) {
      ++inner_count;
      EXPECT_NEAR(ref.radiosity[j].x, 2.0, 1e-4) << "reference, inner patch " << j;
      inner_sq += mesh.area[j] * (est[j].x - 2.0) * (est[j].x - 2.0);
      inner_area += mesh.area[j];
    } else {
      EXPECT_NEAR(ref.radiosity[j].x, 1.0, 1e-5) << "reference, outer patch " << j;
      EXPECT_EQ(est[j].x, 1.0f) << "bundles, outer patch " << j;
    }
  }
  EXPECT_EQ(inner_count * 2, mesh.size());
  EXPECT_LT(std::sqrt(inner_sq / inner_area) / 2.0, 0.0015);
}

}  // namespace
}  // namespace sirad
