// sirad: a polygon face cut into triangles (OBJ n-gons as Blender writes them: a wall with a door
// cut by a Boolean is one concave face), and convex polygons cut by a plane (the gap cuts' and the
// mesher's splits).
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace sirad {

// Concave faces with more corners are refused (ear clipping is quadratic in them).
inline constexpr std::size_t kMaxConcaveCorners = 1024;

// Triangles, as indices into `corners` in the face's own winding, that tile the simple polygon
// `corners` (3 or more, roughly planar). A face whose corners all turn one way about its Newell
// normal and whose fan from corner 0 has no flat triangle is cut as that fan; any other face by
// ear clipping in its plane, where corners on a straight edge (no turn) are dropped rather than
// made into flat triangles. A face with no area (Newell normal 0) is returned as its fan, for the
// caller's degenerate-triangle rule. Throws sirad::Error, without naming the face (the caller
// does), for a polygon that crosses itself or a concave one of more than kMaxConcaveCorners.
std::vector<std::array<uint32_t, 3>> triangulate_polygon(std::span<const glm::vec3> corners);

// The convex hull of the points `q` (Andrew's monotone chain), counter-clockwise, as indices into
// `q`, each corner once; a point whose turn against a hull edge is at most `flat` (twice the area
// of the triangle they make) is left out, so points on its edges within rounding are not
// corners. Collinear or too few points give fewer than 3 indices.
std::vector<std::size_t> convex_hull(std::span<const glm::dvec2> q, double flat);

// Whether point x lies in triangle q (its edges included), with x's barycentric coordinates in
// `w`; false for a triangle with no area. The lightmap's atlas (which chart a texel is) and its
// bake (which face a sample lands on) ask the same question of the same UV triangles.
bool in_triangle(const std::array<glm::dvec2, 3>& q, const glm::dvec2& x, glm::dvec3& w);

// Splits the convex polygon `p` by the plane dot(x - o, m) = 0 into the parts where it is >= 0
// (`in`) and <= 0 (`out`), corners kept in p's order (a corner on the plane goes to both).
void split_convex(std::span<const glm::dvec3> p, const glm::dvec3& o, const glm::dvec3& m, std::vector<glm::dvec3>& in,
                  std::vector<glm::dvec3>& out);

}  // namespace sirad
