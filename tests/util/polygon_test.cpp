// sirad tests: polygon faces cut into triangles (util/polygon.h).
#include "util/polygon.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include <glm/geometric.hpp>

#include "util/error.h"

namespace sirad {
namespace {

// Twice the signed area of triangle (a, b, c) in the z = 0 plane.
double twice_area(glm::dvec3 a, glm::dvec3 b, glm::dvec3 c) { return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x); }

// Whether q lies inside the polygon (even-odd rule, z = 0).
bool inside(const std::vector<glm::vec3>& poly, glm::dvec3 q) {
  bool in = false;
  for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const glm::dvec3 a(poly[i]), b(poly[j]);
    if ((a.y > q.y) != (b.y > q.y) && q.x < (b.x - a.x) * (q.y - a.y) / (b.y - a.y) + a.x) in = !in;
  }
  return in;
}

// The triangles of a simple polygon in z = 0 tile it: each winds as the polygon does (positive
// area), lies inside it (its centroid and its edges' midpoints pulled towards the centroid), and
// their areas sum to the polygon's (shoelace) to rounding.
void expect_tiles(const std::vector<glm::vec3>& poly) {
  const auto tris = triangulate_polygon(poly);
  double polygon = 0.0, sum = 0.0;
  for (std::size_t i = 0; i < poly.size(); ++i)
    polygon += twice_area(glm::dvec3(0.0), glm::dvec3(poly[i]), glm::dvec3(poly[(i + 1) % poly.size()]));
  for (const auto& t : tris) {
    const glm::dvec3 a(poly[t[0]]), b(poly[t[1]]), c(poly[t[2]]);
    const double area = twice_area(a, b, c);
    EXPECT_GT(area, 0.0);
    sum += area;
    const glm::dvec3 centre = (a + b + c) / 3.0;
    EXPECT_TRUE(inside(poly, centre)) << centre.x << " " << centre.y;
    for (const glm::dvec3& m : {(a + b) / 2.0, (b + c) / 2.0, (c + a) / 2.0})
      EXPECT_TRUE(inside(poly, m + 1e-6 * (centre - m))) << m.x << " " << m.y;
  }
  EXPECT_NEAR(sum, polygon, 1e-9 * std::fabs(polygon));
}

TEST(Polygon, ConvexFacesAreTheirFan) {
  const std::vector<glm::vec3> pentagon{{0, 0, 0}, {2, 0, 0}, {3, 1, 0}, {1, 2, 0}, {-1, 1, 0}};
  const auto tris = triangulate_polygon(pentagon);
  ASSERT_EQ(tris.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i)
    EXPECT_EQ(tris[i], (std::array<uint32_t, 3>{0u, static_cast<uint32_t>(i + 1), static_cast<uint32_t>(i + 2)}));
}

// A wall with a door cut by a Boolean, as Blender writes it: one 8-cornered face, concave at the
// door's two upper corners. Its fan from corner 0 crosses the doorway.
TEST(Polygon, AWallWithADoorIsCutInsideItsOutline) {
  const std::vector<glm::vec3> wall{{0, 0, 0}, {1, 0, 0}, {1, 2.1f, 0}, {1.9f, 2.1f, 0},
                                    {1.9f, 0, 0}, {4, 0, 0}, {4, 2.6f, 0}, {0, 2.6f, 0}};
  expect_tiles(wall);
  EXPECT_EQ(triangulate_polygon(wall).size(), 6u);
  // The same face starting at every corner, and wound the other way round (read from behind).
  for (std::size_t s = 1; s < wall.size(); ++s) {
    std::vector<glm::vec3> turned(wall.begin() + static_cast<std::ptrdiff_t>(s), wall.end());
    turned.insert(turned.end(), wall.begin(), wall.begin() + static_cast<std::ptrdiff_t>(s));
    expect_tiles(turned);
  }
  std::vector<glm::vec3> back(wall.rbegin(), wall.rend());
  for (glm::vec3& p : back) p.x = -p.x;  // mirrored so that it winds counter-clockwise again
  expect_tiles(back);
}

// Corners on a straight edge (a Boolean's T-junctions) give no flat triangles, also where the
// fan from corner 0 would; a comb with many teeth is cut inside its outline.
TEST(Polygon, StraightCornersAndCombs) {
  const std::vector<glm::vec3> quad_with_midpoints{{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}, {0, 1, 0}};
  expect_tiles(quad_with_midpoints);
  EXPECT_EQ(triangulate_polygon(quad_with_midpoints).size(), 4u);
  std::vector<glm::vec3> comb{{0, 0, 0}};
  for (int k = 0; k < 20; ++k) {
    comb.push_back({2.0f * k + 1.0f, 0, 0});
    comb.push_back({2.0f * k + 1.0f, -3, 0});
    comb.push_back({2.0f * k + 2.0f, -3, 0});
    comb.push_back({2.0f * k + 2.0f, 0, 0});
  }
  comb.push_back({41, 0, 0});
  comb.push_back({41, 1, 0});
  comb.push_back({0, 1, 0});
  expect_tiles(comb);
}

// A tilted face is cut in its own plane: the triangles' normals all point where the face's does.
TEST(Polygon, TiltedFacesKeepTheirNormal) {
  std::vector<glm::vec3> l{{0, 0, 0}, {2, 0, 0}, {2, 1, 1}, {1, 1, 1}, {1, 2, 2}, {0, 2, 2}};
  const auto tris = triangulate_polygon(l);
  ASSERT_EQ(tris.size(), 4u);
  const glm::dvec3 n = glm::normalize(glm::dvec3(0, -1, 1));
  double area = 0.0;
  for (const auto& t : tris) {
    const glm::dvec3 c = glm::cross(glm::dvec3(l[t[1]] - l[t[0]]), glm::dvec3(l[t[2]] - l[t[0]]));
    EXPECT_NEAR(glm::dot(glm::normalize(c), n), 1.0, 1e-9);
    area += glm::length(c) / 2.0;
  }
  EXPECT_NEAR(area, 3.0 * std::sqrt(2.0), 1e-6);
}

TEST(Polygon, SelfCrossingAndHugeConcaveFacesAreRefused) {
  // A bow tie crosses itself: no ear can be cut from it.
  const std::vector<glm::vec3> bow{{0, 0, 0}, {2, 2, 0}, {2, 0, 0}, {1, 3, 0}, {0, 2, 0}, {1, -1, 0}};
  EXPECT_THROW(triangulate_polygon(bow), Error);
  std::vector<glm::vec3> star;
  for (std::size_t k = 0; k < 2 * kMaxConcaveCorners; ++k) {
    const double a = 2.0 * 3.141592653589793 * static_cast<double>(k) / (2.0 * kMaxConcaveCorners);
    const double r = k % 2 ? 1.0 : 0.5;
    star.push_back({static_cast<float>(r * std::cos(a)), static_cast<float>(r * std::sin(a)), 0.0f});
  }
  try {
    triangulate_polygon(star);
    ADD_FAILURE() << "a concave face of " << star.size() << " corners was taken";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("2048 corners"), std::string::npos) << e.what();
  }
  star.resize(64);
  star.push_back({0, 0, 0});
  expect_tiles(star);
}

}  // namespace
}  // namespace sirad
