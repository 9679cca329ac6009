// sirad: where faces meet. A wall stands on a floor slab whose face runs on under it; an inner
// wall meets an outer wall in the middle of its face; a table leg stands on a floor. A patch of
// the face that straddles such a foot has one radiosity for its open part and its covered part
// (or for the two rooms either side of a zero-thickness wall): it sends the covered part's
// share into the wall, or one room's light into the other: the wall under a lamp comes out dark,
// a room seen through a door bright (bench/RESULTS.md, "what is left of the image's bias near
// the lamp"). The mesher splits such patches along the foot (scene/mesh.h).
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "scene/scene.h"

namespace sirad {

// A segment in a face's plane along which another face meets it; `facing`, in the plane, the
// side that face's front looks to (behind it, the inside of a wall or a leg).
struct ContactSegment {
  glm::dvec3 p, q;
  glm::dvec3 facing;
};

// How near a face must come to another's plane to meet it: 1e-5 of the scene's bounding
// radius, the depth tie of the coincident-face rule (DESIGN.md section 1).
double contact_tolerance(const Scene& scene);

// For each triangle of `scene`, the segments (within it, at least `tolerance` long) along which
// another triangle that reaches in front of it meets its plane, standing on it (an edge within
// `tolerance` of the plane) or crossing it; faces within 25 degrees of parallel to it none. A
// segment that two faces facing the same side make (one face cut in two) counts once; a face
// and its twin make two. Emitting and unlit triangles get none. At most
// kMaxContactsPerFace a triangle, and pairs looked at bounded by kMaxContactPairs (past it the
// rest get none): the same answer in every process.
inline constexpr std::size_t kMaxContactsPerFace = 64;
inline constexpr double kMaxContactPairs = 1e8;
std::vector<std::vector<ContactSegment>> contact_segments(const Scene& scene, double tolerance);

// Whether a point of a face (the centre of a piece or a sub-triangle of it; `contacts` the
// face's segments) lies inside a solid that stands on it (under a wall's foot, a table leg). Two
// tests, both needed:
// - behind the face that stands nearest: of the segments the point lies beside, the nearest
//   has it behind its face, and none at that distance has it in front (a zero-thickness wall's
//   twin);
// - the ray from just in front of it along the face's normal meets a back first: at the first
//   place it meets something (faces within `tolerance` of one distance), a back that is not a
//   twin's (a face and its reversed copy, a two-sided surface, are passed through); a front
//   there, or nothing met, is open.
// So a floor behind a one-sided outer wall, which sees the sky, is kept, as is the floor under
// a two-sided table top. Double precision against the triangles in front of the face whose
// extent across its normal overlaps the face's: the same answer in every process. Past
// kMaxCoverTests ray-triangle tests and candidate looks together, every point is open (kept),
// and so is one whose ray meets more than kMaxFacesAtOnePlace faces at one place.
inline constexpr double kMaxCoverTests = 2e8;
inline constexpr std::size_t kMaxFacesAtOnePlace = 64;
class CoverTest {
 public:
  CoverTest(const Scene& scene, double tolerance) : scene_(scene), tolerance_(tolerance) {}
  bool inside(uint32_t face, const std::vector<ContactSegment>& contacts, const glm::dvec3& point);

 private:
  struct Candidate {
    std::array<glm::dvec3, 3> p;
    double lo_u, hi_u, lo_v, hi_v;  // extent across the face's normal
  };
  const Scene& scene_;
  double tolerance_;
  double tests_ = 0.0;
  uint32_t face_ = UINT32_MAX;  // whose candidates are held
  glm::dvec3 normal_{0.0}, u_{0.0}, v_{0.0};
  std::vector<Candidate> candidates_;
  struct Hit {
    double t;
    bool back;
    const Candidate* face;
  };
  std::vector<Hit> hits_;
};

// Clips the segment [p, q] (in the plane of triangle t, whose corners run counter-clockwise
// seen from the front of its normal n) to the triangle; false when none of it lies inside.
bool clip_to_triangle(const std::array<glm::dvec3, 3>& t, const glm::dvec3& n, glm::dvec3& p, glm::dvec3& q);

}  // namespace sirad
