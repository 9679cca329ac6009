// sirad tests: faces cut along the outline of a surface across a narrow gap from them, a lamp's
// or any other's (scene/scene.h cut_along_gaps). The lamp's cuts and strips are tested with the
// first shot (tests/engine/shot_test.cpp, GapCuts.*); these are the other surfaces'.
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <gtest/gtest.h>

#include "scene/scene.h"
#include "tests/coincident_scenes.h"

namespace sirad {
namespace {

using glm::dvec3;

// A closed room 4 x 3 x 4 m (room_shell) lit by a ceiling lamp, with a wardrobe, a closed box 0.6 x 2 x 1.2 m (x, y, z)
// standing on the floor, its back `gap` in front of the wall x = 4, everything turned by
// `rotation`; `l_shaped` makes its back two rectangles that do not fill their hull (an L, as a
// Boolean leaves a face) and leaves the rest of the box out.
test::ObjBuilder wardrobe_room(double gap, const glm::dmat3& rotation, bool l_shaped = false) {
  test::ObjBuilder o(rotation);
  test::room_shell(o);
  o.material("lamp");
  o.quad({1.5, 2.95, 1.5}, {2.5, 2.95, 1.5}, {2.5, 2.95, 2.5}, {1.5, 2.95, 2.5});
  o.material("panel");
  const double x0 = 4.0 - gap - 0.6, x1 = 4.0 - gap, y1 = 2.0, z0 = 1.0, z1 = 2.2;
  if (l_shaped) {  // the back only, facing +x: the lower 1 m over the full width, the upper half of it
    o.wall_x(x1, 0.0, 1.0, z0, z1, true);
    o.wall_x(x1, 1.0, y1, z0, 1.6, true);
    return o;
  }
  o.wall_x(x1, 0.0, y1, z0, z1, true);   // the back, towards the wall
  o.wall_x(x0, 0.0, y1, z0, z1, false);  // the front, towards the room
  o.quad({x0, y1, z0}, {x0, y1, z1}, {x1, y1, z1}, {x1, y1, z0});  // the top
  o.quad({x0, 0.0, z0}, {x1, 0.0, z0}, {x1, y1, z0}, {x0, y1, z0});  // towards -z
  o.quad({x0, 0.0, z1}, {x0, y1, z1}, {x1, y1, z1}, {x1, 0.0, z1});  // towards +z
  return o;
}

// The triangles of the wall x = 4 (facing -x), in the room's own frame: each lies wholly behind
// the wardrobe's back (y 0..2, z 1..2.2) or wholly beside it, is Triangle::in_gap exactly when
// behind, and the wall keeps its area. Returns the area behind and the wall's triangle count.
std::pair<double, std::size_t> wall_behind(const Scene& s, const glm::dmat3& rotation, double y1 = 2.0, double z1 = 2.2) {
  const glm::dmat3 back = glm::transpose(rotation);
  double behind = 0.0, wall = 0.0;
  std::size_t count = 0;
  for (const Triangle& t : s.triangles) {
    const dvec3 a = back * dvec3(t.p[0]), b = back * dvec3(t.p[1]), c = back * dvec3(t.p[2]);
    const dvec3 n = glm::cross(b - a, c - a);
    if (!(std::abs(a.x - 4.0) < 1e-5 && std::abs(b.x - 4.0) < 1e-5 && std::abs(c.x - 4.0) < 1e-5 && n.x < 0.0)) continue;
    ++count;
    int in = 0;
    for (const dvec3& p : {a, b, c}) in += p.y <= y1 + 1e-5 && p.z >= 1.0 - 1e-5 && p.z <= z1 + 1e-5;
    const dvec3 m = (a + b + c) / 3.0;
    const bool centre_in = m.y < y1 && m.z > 1.0 && m.z < z1;
    EXPECT_EQ(in == 3, centre_in) << "a triangle across the outline at y " << m.y << " z " << m.z;
    EXPECT_EQ(t.in_gap, centre_in) << "y " << m.y << " z " << m.z;
    const double area = 0.5 * glm::length(n);
    wall += area;
    if (centre_in) behind += area;
  }
  EXPECT_NEAR(wall, 12.0, 1e-4) << "the wall keeps its area";
  return {behind, count};
}

// A wardrobe 5 cm in front of a wall (gap / its back's extent 0.021, under kGapCutSurface): the
// wall is cut along the outline of the wardrobe's back, so that no patch there averages the
// room's light with the dark gap behind it; turned obliquely, so that no coordinate is exact.
TEST(GapCuts, AWallBehindAWardrobeIsCutAlongItsOutline) {
  const glm::dmat3 r = test::oblique(23.0);
  const Scene s = wardrobe_room(0.05, r).scene("wardrobe 5 cm from a wall", test::kMtl);
  const auto [behind, count] = wall_behind(s, r);
  EXPECT_NEAR(behind, 2.0 * 1.2, 1e-4);
  EXPECT_GT(count, 2u);
  // The wardrobe's own back lies wholly over the wall: marked, not cut.
  std::size_t back_marked = 0;
  for (const Triangle& t : s.triangles) {
    const dvec3 a = glm::transpose(r) * dvec3(t.p[0]);
    const dvec3 n = glm::transpose(r) * glm::cross(dvec3(t.p[1] - t.p[0]), dvec3(t.p[2] - t.p[0]));
    if (std::abs(a.x - 3.95) < 1e-5 && n.x > 0.0) back_marked += t.in_gap;
  }
  EXPECT_EQ(back_marked, 2u);
}

// 45 cm out (past kGapCutSurface x the back's 2.33 m) the gap is a room's corner, not a slit:
// nothing is cut.
TEST(GapCuts, AWardrobeFarFromAWallLeavesItWhole) {
  const Scene s = wardrobe_room(0.45, glm::dmat3(1.0)).scene("wardrobe 45 cm from a wall", test::kMtl);
  const auto [behind, count] = wall_behind(s, glm::dmat3(1.0));
  EXPECT_EQ(count, 2u);
  EXPECT_EQ(behind, 0.0);
  ASSERT_GT(0.45, kGapCutSurface * std::hypot(2.0, 1.2));
}

// A surface that does not fill its convex hull (an L, as a Boolean leaves a face) is no outline:
// cutting along its triangles' edges would cut the wall along lines no shadow follows.
TEST(GapCuts, ASurfaceThatIsNoConvexOutlineCutsNothing) {
  const Scene s = wardrobe_room(0.05, glm::dmat3(1.0), true).scene("an L 5 cm from a wall", test::kMtl);
  const auto [behind, count] = wall_behind(s, glm::dmat3(1.0));
  EXPECT_EQ(count, 2u);
  EXPECT_EQ(behind, 0.0);
}

// A rug 2 mm over the floor, or laid on it (zero gap: the later face is on top by the
// coincident-face rule): the floor is cut along the rug's outline (the rug's back faces the
// floor), the pieces under it are marked, and the rug itself, the later face, is neither cut nor
// marked.
TEST(GapCuts, AFloorUnderARugIsCutAlongItsOutline) {
  const glm::dmat3 r = test::oblique(-31.0);
  for (const double gap : {0.002, 0.0}) {
    SCOPED_TRACE(gap);
    const Scene s = test::rug_room(gap, r);
    const glm::dmat3 back = glm::transpose(r);
    double under = 0.0, floor = 0.0;
    std::size_t rug = 0;
    for (const Triangle& t : s.triangles) {
      if (s.materials[t.material].name == "rug") {
        ++rug;
        EXPECT_FALSE(t.in_gap);
        continue;
      }
      const dvec3 a = back * dvec3(t.p[0]), b = back * dvec3(t.p[1]), c = back * dvec3(t.p[2]);
      const dvec3 n = glm::cross(b - a, c - a);
      if (!(std::abs(a.y) < 1e-5 && std::abs(b.y) < 1e-5 && std::abs(c.y) < 1e-5 && n.y > 0.0)) continue;
      const dvec3 m = (a + b + c) / 3.0;
      const bool centre_in = m.x > 1.1 && m.x < 2.7 && m.z > 1.3 && m.z < 2.5;
      EXPECT_EQ(t.in_gap, centre_in) << "x " << m.x << " z " << m.z;
      floor += 0.5 * glm::length(n);
      if (centre_in) under += 0.5 * glm::length(n);
    }
    EXPECT_EQ(rug, 2u);
    EXPECT_NEAR(floor, 16.0, 1e-4);
    EXPECT_NEAR(under, 1.6 * 1.2, 1e-4);
  }
}

// A one-sided lamp 1.5 cm under a ceiling: its back, black, faces the ceiling, which is cut along
// its outline as along any surface's (the emitter's own cuts and strips are for a front that
// faces the face, tests/engine/shot_test.cpp): the gap is dark, so no strips.
TEST(GapCuts, ACeilingOverALampsBackIsCutAlongItsOutline) {
  test::ObjBuilder o;
  test::room_shell(o);
  o.material("lamp");
  o.quad({1.4, 2.985, 1.7}, {2.6, 2.985, 1.7}, {2.6, 2.985, 2.3}, {1.4, 2.985, 2.3});  // facing down
  const Scene s = o.scene("a one-sided lamp 1.5 cm under a ceiling", test::kMtl);
  double over = 0.0, ceiling = 0.0;
  for (const Triangle& t : s.triangles) {
    const dvec3 a(t.p[0]), b(t.p[1]), c(t.p[2]);
    const dvec3 n = glm::cross(b - a, c - a);
    EXPECT_FALSE(t.whole);
    if (!(std::abs(a.y - 3.0) < 1e-6 && n.y < 0.0)) continue;
    const dvec3 m = (a + b + c) / 3.0;
    const bool centre_in = m.x > 1.4 && m.x < 2.6 && m.z > 1.7 && m.z < 2.3;
    EXPECT_EQ(t.in_gap, centre_in) << "x " << m.x << " z " << m.z;
    ceiling += 0.5 * glm::length(n);
    if (centre_in) over += 0.5 * glm::length(n);
  }
  EXPECT_NEAR(ceiling, 16.0, 1e-4);
  EXPECT_NEAR(over, 1.2 * 0.6, 1e-5);
}

}  // namespace
}  // namespace sirad
