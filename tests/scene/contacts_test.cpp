// Where faces meet (scene/contacts.h) and the mesher's splits along it (scene/mesh.h): a wall
// standing on a floor, a zero-thickness wall, a one-sided wall, a table on legs.
#include "scene/contacts.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "scene/mesh.h"
#include "scene/scene.h"
#include "util/error.h"

namespace sirad {
namespace {

using glm::vec3;

// A room's floor [0, 4] x [0, 4] at y = 0, facing up, as two triangles (its diagonal crosses
// what stands on it); with a ceiling at y = 2.5 facing down when `ceiling`.
Scene floor_scene(bool ceiling) {
  Scene s;
  s.name = "contacts";
  s.materials.push_back({"white", vec3(0.6f), vec3(0.0f)});
  s.objects = {"floor", "ceiling", "thing"};
  s.triangles.push_back({{vec3(0, 0, 0), vec3(0, 0, 4), vec3(4, 0, 4)}, 0, 0, 0});
  s.triangles.push_back({{vec3(0, 0, 0), vec3(4, 0, 4), vec3(4, 0, 0)}, 0, 0, 0});
  if (ceiling) {
    s.triangles.push_back({{vec3(0, 2.5, 0), vec3(4, 2.5, 4), vec3(0, 2.5, 4)}, 0, 0, 1});
    s.triangles.push_back({{vec3(0, 2.5, 0), vec3(4, 2.5, 0), vec3(4, 2.5, 4)}, 0, 0, 1});
  }
  return s;
}

// The quad a b c d as two triangles, turned to face along `facing`.
void quad(Scene& s, vec3 a, vec3 b, vec3 c, vec3 d, vec3 facing) {
  if (glm::dot(glm::cross(b - a, c - a), facing) < 0.0f) std::swap(b, d);
  s.triangles.push_back({{a, b, c}, 0, 0, 2});
  s.triangles.push_back({{a, c, d}, 0, 0, 2});
}

// A closed box [lo, hi], its faces facing out (a wall, a table leg).
void box(Scene& s, vec3 lo, vec3 hi) {
  const vec3 l = lo, h = hi;
  quad(s, {l.x, l.y, l.z}, {l.x, h.y, l.z}, {l.x, h.y, h.z}, {l.x, l.y, h.z}, {-1, 0, 0});
  quad(s, {h.x, l.y, l.z}, {h.x, h.y, l.z}, {h.x, h.y, h.z}, {h.x, l.y, h.z}, {1, 0, 0});
  quad(s, {l.x, l.y, l.z}, {h.x, l.y, l.z}, {h.x, l.y, h.z}, {l.x, l.y, h.z}, {0, -1, 0});
  quad(s, {l.x, h.y, l.z}, {h.x, h.y, l.z}, {h.x, h.y, h.z}, {l.x, h.y, h.z}, {0, 1, 0});
  quad(s, {l.x, l.y, l.z}, {h.x, l.y, l.z}, {h.x, h.y, l.z}, {l.x, h.y, l.z}, {0, 0, -1});
  quad(s, {l.x, l.y, h.z}, {h.x, l.y, h.z}, {h.x, h.y, h.z}, {l.x, h.y, h.z}, {0, 0, 1});
}

// Total length of the contact segments of the triangles of `object`.
double contact_length(const Scene& s, const std::vector<std::vector<ContactSegment>>& contacts, uint32_t object) {
  double length = 0.0;
  for (std::size_t t = 0; t < s.triangles.size(); ++t)
    if (s.triangles[t].object == object)
      for (const ContactSegment& c : contacts[t]) length += glm::length(c.q - c.p);
  return length;
}

// Area of the patches of `object`, and how many have points strictly on both sides of the
// rectangle [x0, x1] x [z0, z1] (in x and z; a patch on the outline's lines is on neither).
struct Footprint {
  double area = 0.0;
  std::size_t straddling = 0, inside = 0;
};
Footprint footprint(const Scene& s, const PatchMesh& mesh, uint32_t object, double x0, double x1, double z0, double z1) {
  constexpr double e = 1e-4;  // well above float rounding at 4 m, well below a patch
  Footprint f;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    if (s.triangles[mesh.source_triangle[j]].object != object) continue;
    f.area += mesh.area[j];
    bool in = false, out = false;
    glm::dvec3 centre(0.0);
    for (uint32_t v : mesh.patches[j]) {
      const glm::dvec3 p(mesh.vertices[v]);
      centre += p / 3.0;
      in = in || (p.x > x0 + e && p.x < x1 - e && p.z > z0 + e && p.z < z1 - e);
      out = out || p.x < x0 - e || p.x > x1 + e || p.z < z0 - e || p.z > z1 + e;
    }
    f.straddling += in && out;
    f.inside += centre.x > x0 && centre.x < x1 && centre.z > z0 && centre.z < z1;
  }
  return f;
}

// A wall 0.2 m thick standing on the floor and touching the ceiling: both are met along its
// outline (2 x (0.2 + 2.5) = 5.4 m each), no patch of either straddles it, and what lies inside
// it is left out (the floor's and the ceiling's area less the wall's footprint, 0.5 m^2). The
// ray from a floor piece under the wall meets the wall's top (a back) where the ceiling's
// underside (a front) touches it, and the ray from a ceiling piece the wall's bottom on the
// floor: a back beside a front that is not its twin is a back.
TEST(MeshContacts, AWallsFootSplitsTheFloorAndWhatIsUnderItIsLeftOut) {
  Scene s = floor_scene(true);
  box(s, {1.5f, 0.0f, 0.5f}, {1.7f, 2.5f, 3.0f});
  const auto contacts = contact_segments(s, contact_tolerance(s));
  EXPECT_NEAR(contact_length(s, contacts, 0), 5.4, 1e-6);
  EXPECT_NEAR(contact_length(s, contacts, 1), 5.4, 1e-6);
  for (std::size_t target : {300u, 2000u, 20000u}) {  // at 20,000, whole sub-triangles lie under the wall
    const PatchMesh mesh = mesh_scene(s, {.target_patches = target});
    for (uint32_t object : {0u, 1u}) {
      const Footprint f = footprint(s, mesh, object, 1.5, 1.7, 0.5, 3.0);
      EXPECT_EQ(f.straddling, 0u) << s.objects[object] << " at " << target;
      EXPECT_EQ(f.inside, 0u) << s.objects[object] << " at " << target;
      EXPECT_NEAR(f.area, 16.0 - 0.5, 1e-5 * 16.0) << s.objects[object] << " at " << target;
    }
  }
}

// A zero-thickness wall (a face and its reversed twin, as add_back_faces makes) has a room on
// each side: the floor is split along its foot and none of it is left out; likewise beside a
// one-sided wall, whose back sees the ceiling (or, without one, nothing) and so is open.
TEST(MeshContacts, BesideAZeroThicknessOrOneSidedWallTheFloorIsKept) {
  for (int twin = 0; twin < 2; ++twin)
    for (int ceiling = 0; ceiling < 2; ++ceiling) {
      Scene s = floor_scene(ceiling != 0);
      const vec3 a(2.0f, 0.0f, 0.5f), b(2.0f, 2.5f, 0.5f), c(2.0f, 2.5f, 3.0f), d(2.0f, 0.0f, 3.0f);
      quad(s, a, b, c, d, {1, 0, 0});
      if (twin) quad(s, a, b, c, d, {-1, 0, 0});
      const PatchMesh mesh = mesh_scene(s, {.target_patches = 1000});
      const std::string what = std::string(twin ? "two-sided" : "one-sided") + (ceiling ? ", ceiling" : "");
      // No floor patch crosses the line x = 2 beside the foot (0.5 < z < 3): where a patch
      // reaches both sides of it, the z its edges cross it at are outside that.
      std::size_t straddling = 0;
      for (std::size_t j = 0; j < mesh.size(); ++j) {
        if (s.triangles[mesh.source_triangle[j]].object != 0) continue;
        double lo = 1e9, hi = -1e9;
        bool left = false, right = false;
        for (int k = 0; k < 3; ++k) {
          const glm::dvec3 u(mesh.vertices[mesh.patches[j][k]]), v(mesh.vertices[mesh.patches[j][(k + 1) % 3]]);
          left = left || u.x < 2.0 - 1e-4;
          right = right || u.x > 2.0 + 1e-4;
          if (std::abs(u.x - 2.0) < 1e-6) lo = std::min(lo, u.z), hi = std::max(hi, u.z);
          if ((u.x - 2.0) * (v.x - 2.0) >= 0.0) continue;
          const double z = u.z + (v.z - u.z) * (2.0 - u.x) / (v.x - u.x);
          lo = std::min(lo, z), hi = std::max(hi, z);
        }
        straddling += left && right && hi > 0.5 + 1e-4 && lo < 3.0 - 1e-4;
      }
      EXPECT_EQ(straddling, 0u) << what;
      EXPECT_NEAR(footprint(s, mesh, 0, 0, 4, 0, 4).area, 16.0, 1e-5 * 16.0) << what;
      if (ceiling) {
        EXPECT_NEAR(footprint(s, mesh, 1, 0, 4, 0, 4).area, 16.0, 1e-5 * 16.0) << what;
      }
    }
}

// A table: a two-sided top 0.75 m up on four closed legs 5 cm square. The legs' feet are left
// out; the floor under the top is kept (the ray from it passes the top's two sides and meets
// nothing, or the ceiling's front).
TEST(MeshContacts, ATablesLegsAreLeftOutAndTheFloorUnderItsTopIsNot) {
  for (int ceiling = 0; ceiling < 2; ++ceiling) {
    Scene s = floor_scene(ceiling != 0);
    const vec3 a(1.0f, 0.75f, 1.0f), b(3.0f, 0.75f, 1.0f), c(3.0f, 0.75f, 3.0f), d(1.0f, 0.75f, 3.0f);
    quad(s, a, b, c, d, {0, 1, 0});
    quad(s, a, b, c, d, {0, -1, 0});
    for (float x : {1.1f, 2.85f})
      for (float z : {1.1f, 2.85f}) box(s, {x, 0.0f, z}, {x + 0.05f, 0.75f, z + 0.05f});
    const PatchMesh mesh = mesh_scene(s, {.target_patches = 3000});
    EXPECT_NEAR(footprint(s, mesh, 0, 0, 4, 0, 4).area, 16.0 - 4 * 0.0025, 1e-5 * 16.0) << "ceiling " << ceiling;
    for (float x : {1.1f, 2.85f})
      for (float z : {1.1f, 2.85f}) {
        const Footprint f = footprint(s, mesh, 0, x, x + 0.05, z, z + 0.05);
        EXPECT_EQ(f.straddling, 0u);
        EXPECT_EQ(f.inside, 0u);
      }
  }
}

// One patch per face (both options zero: the meshes that add_back_faces and mark_unlit_faces
// match to their faces) is never split, whatever stands where.
TEST(MeshContacts, OnePatchPerFaceIsNeverSplit) {
  Scene s = floor_scene(true);
  box(s, {1.5f, 0.0f, 0.5f}, {1.7f, 2.5f, 3.0f});
  const PatchMesh mesh = mesh_scene(s, {});
  ASSERT_EQ(mesh.size(), s.triangles.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) EXPECT_EQ(mesh.source_triangle[j], j);
}

// A target counts the patches the splits add and drop. The grid is made coarser once by what the
// first meshing added, X1; the second adds X2 < X1 (fewer cells cross the contacts), so the count
// lands at the grid's closest count to target - X1, plus X2: under the target by X1 - X2, about
// X1^2 / 2T (X falls as 1 / edge, the grid as 1 / edge^2) plus the grid's step. At 2,000 patches
// and more the Cornell box's blocks add about 5 %, so within 1 % (the steps here are a few
// patches).
TEST(MeshContacts, ATargetCountsThePatchesTheSplitsAddAndDrop) {
  const Scene s = builtin_cornell();
  for (std::size_t target : {2000u, 8000u, 30000u}) {
    const std::size_t size = mesh_scene(s, {.target_patches = target}).size();
    EXPECT_LT(std::abs(static_cast<double>(size) - static_cast<double>(target)), 0.01 * static_cast<double>(target)) << target;
  }
}

// A node bounded to the coordinator's patch count meshes the same scene: the first meshing for
// a target may pass it (kSplitHeadroom), the final may not.
TEST(MeshContacts, TheFinalCountIsWhatMaxPatchesBounds) {
  const Scene s = builtin_cornell();
  const PatchMesh first = mesh_scene(s, {.target_patches = 300});
  const PatchMesh again = mesh_scene(s, {.target_patches = 300, .max_patches = first.size()});
  EXPECT_EQ(again.hash, first.hash);
  try {
    mesh_scene(s, {.target_patches = 300, .max_patches = first.size() - 1});
    ADD_FAILURE() << "one patch fewer than the meshing makes was allowed";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("more than"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sirad
