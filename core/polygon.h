// sirad: a polygon face cut into triangles (OBJ n-gons as Blender writes them: a wall with a door
// cut by a Boolean is one concave face).
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

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

}  // namespace sirad
