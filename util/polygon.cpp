// sirad: a polygon face cut into triangles (util/polygon.h).
#include "util/polygon.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include "util/error.h"

namespace sirad {
namespace {

double cross(glm::dvec2 a, glm::dvec2 b) { return a.x * b.y - a.y * b.x; }

std::vector<std::array<uint32_t, 3>> fan(std::size_t n) {
  std::vector<std::array<uint32_t, 3>> out;
  for (std::size_t i = 1; i + 1 < n; ++i)
    out.push_back({0u, static_cast<uint32_t>(i), static_cast<uint32_t>(i + 1)});
  return out;
}

// Refuses a face that crosses itself, which has no inside to tile: two edges that are not
// neighbours and cross properly (each one's ends strictly on both sides of the other).
void refuse_crossing_edges(const std::vector<glm::dvec2>& p, double eps) {
  const std::size_t n = p.size();
  for (std::size_t i = 0; i < n; ++i) {
    const glm::dvec2 a = p[i], b = p[(i + 1) % n];
    for (std::size_t j = i + 2; j < n; ++j) {
      if (i == 0 && j == n - 1) continue;
      const glm::dvec2 c = p[j], d = p[(j + 1) % n];
      const double c1 = cross(b - a, c - a), c2 = cross(b - a, d - a), c3 = cross(d - c, a - c), c4 = cross(d - c, b - c);
      if (((c1 > eps && c2 < -eps) || (c1 < -eps && c2 > eps)) && ((c3 > eps && c4 < -eps) || (c3 < -eps && c4 > eps)))
        fail("a face of {} corners that crosses itself (edges {} and {}; it cannot be cut into triangles)", n, i + 1, j + 1);
    }
  }
}

// Ear clipping: a corner that turns left and whose triangle holds no other corner (corners at
// the same place as one of its three, as a hole's bridge leaves, do not count) is cut off. The
// search goes on from the last cut, so a face is cut in O(n^2) steps in all but contrived cases.
// Counter-clockwise corners `p` in their plane; turns below eps are straight.
std::vector<std::array<uint32_t, 3>> ear_clip(const std::vector<glm::dvec2>& p, double eps) {
  const std::size_t n = p.size();
  auto turn = [&](uint32_t a, uint32_t b, uint32_t c) { return cross(p[b] - p[a], p[c] - p[b]); };
  auto inside = [&](glm::dvec2 q, uint32_t a, uint32_t b, uint32_t c) {
    return cross(p[b] - p[a], q - p[a]) >= -eps && cross(p[c] - p[b], q - p[b]) >= -eps &&
           cross(p[a] - p[c], q - p[c]) >= -eps;
  };
  std::vector<uint32_t> ring(n);
  for (std::size_t i = 0; i < n; ++i) ring[i] = static_cast<uint32_t>(i);
  std::vector<std::array<uint32_t, 3>> out;
  std::size_t k = 0, tried = 0;
  while (ring.size() > 3) {
    const std::size_t m = ring.size();
    if (tried == m) fail("a face of {} corners that crosses itself (it cannot be cut into triangles)", n);
    k %= m;
    const uint32_t a = ring[(k + m - 1) % m], b = ring[k], c = ring[(k + 1) % m];
    const double t = turn(a, b, c);
    bool ear = std::fabs(t) <= eps;  // straight (or a spike): b is dropped, no triangle
    if (!ear && t > 0.0) {
      ear = true;
      for (uint32_t q : ring) {
        if (q == a || q == b || q == c || p[q] == p[a] || p[q] == p[b] || p[q] == p[c]) continue;
        if (inside(p[q], a, b, c)) {
          ear = false;
          break;
        }
      }
      if (ear) out.push_back({a, b, c});
    }
    if (ear) {
      ring.erase(ring.begin() + static_cast<std::ptrdiff_t>(k));
      if (k > 0) --k;
      tried = 0;
    } else {
      ++k;
      ++tried;
    }
  }
  if (std::fabs(turn(ring[0], ring[1], ring[2])) > eps) out.push_back({ring[0], ring[1], ring[2]});
  if (out.empty()) return fan(n);
  return out;
}

}  // namespace

std::vector<std::array<uint32_t, 3>> triangulate_polygon(std::span<const glm::vec3> corners) {
  const std::size_t n = corners.size();
  if (n < 3) fail("a face needs at least 3 corners (got {})", n);
  if (n == 3) return fan(3);

  // The plane: Newell's normal (robust for non-planar and concave faces), two axes in it.
  glm::dvec3 normal(0.0);
  for (std::size_t i = 0; i < n; ++i) {
    const glm::dvec3 a(corners[i]), b(corners[(i + 1) % n]);
    normal += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
  }
  const double length = glm::length(normal);
  if (!std::isfinite(length)) return fan(n);
  double size = 0.0;  // the longest distance from corner 0
  for (std::size_t i = 1; i < n; ++i) size = std::max(size, glm::length(glm::dvec3(corners[i]) - glm::dvec3(corners[0])));
  if (!(length > 1e-12 * size * size)) {
    // No area: a degenerate face (its fan is flat, for the caller's rule), or one whose parts
    // wind both ways (a bow tie), which crosses itself.
    for (const auto& t : fan(n)) {
      const glm::dvec3 a(corners[t[0]]), b(corners[t[1]]), c(corners[t[2]]);
      if (glm::length(glm::cross(b - a, c - a)) > 1e-12 * size * size)
        fail("a face of {} corners that crosses itself (it cannot be cut into triangles)", n);
    }
    return fan(n);
  }
  normal /= length;
  const glm::dvec3 helper = std::fabs(normal.x) < 0.6 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  const glm::dvec3 u = glm::normalize(glm::cross(helper, normal));
  const glm::dvec3 v = glm::cross(normal, u);
  // In (u, v) the face winds counter-clockwise: Newell's normal is its area vector.
  std::vector<glm::dvec2> p(n);
  glm::dvec2 lo(HUGE_VAL), hi(-HUGE_VAL);
  for (std::size_t i = 0; i < n; ++i) {
    const glm::dvec3 d = glm::dvec3(corners[i]) - glm::dvec3(corners[0]);
    p[i] = {glm::dot(d, u), glm::dot(d, v)};
    lo = glm::min(lo, p[i]);
    hi = glm::max(hi, p[i]);
  }
  // Turns below eps (relative to the face's size, squared) are straight.
  const glm::dvec2 extent = hi - lo;
  const double eps = 1e-12 * std::max(extent.x, extent.y) * std::max(extent.x, extent.y);
  auto turn = [&](uint32_t a, uint32_t b, uint32_t c) { return cross(p[b] - p[a], p[c] - p[b]); };

  bool convex = true;
  for (std::size_t i = 0; i < n && convex; ++i)
    convex = turn(static_cast<uint32_t>((i + n - 1) % n), static_cast<uint32_t>(i), static_cast<uint32_t>((i + 1) % n)) >= -eps;
  for (std::size_t i = 1; i + 1 < n && convex; ++i)
    convex = cross(p[i] - p[0], p[i + 1] - p[0]) > eps;
  if (convex) return fan(n);
  if (n > kMaxConcaveCorners) fail("a concave face of {} corners (at most {} are cut into triangles)", n, kMaxConcaveCorners);
  refuse_crossing_edges(p, eps);
  return ear_clip(p, eps);
}

std::vector<std::size_t> convex_hull(std::span<const glm::dvec2> q, double flat) {
  if (q.empty()) return {};
  auto turn = [&](std::size_t o, std::size_t a, std::size_t b) {
    return (q[a].x - q[o].x) * (q[b].y - q[o].y) - (q[a].y - q[o].y) * (q[b].x - q[o].x);
  };
  std::vector<std::size_t> order(q.size());
  for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return q[a].x < q[b].x || (q[a].x == q[b].x && q[a].y < q[b].y); });
  std::vector<std::size_t> hull(2 * order.size() + 1);
  std::size_t k = 0;
  for (std::size_t i = 0; i < order.size(); ++i) {  // the lower chain
    while (k >= 2 && turn(hull[k - 2], hull[k - 1], order[i]) <= flat) --k;
    hull[k++] = order[i];
  }
  for (std::size_t i = order.size() - 1, lower = k + 1; i-- > 0;) {  // the upper chain
    while (k >= lower && turn(hull[k - 2], hull[k - 1], order[i]) <= flat) --k;
    hull[k++] = order[i];
  }
  hull.resize(k - 1);  // the last point is the first
  return hull;
}

void split_convex(std::span<const glm::dvec3> p, const glm::dvec3& o, const glm::dvec3& m, std::vector<glm::dvec3>& in,
                  std::vector<glm::dvec3>& out) {
  in.clear();
  out.clear();
  for (std::size_t i = 0; i < p.size(); ++i) {
    const glm::dvec3 &a = p[i], &b = p[(i + 1) % p.size()];
    const double sa = glm::dot(a - o, m), sb = glm::dot(b - o, m);
    if (sa >= 0.0) in.push_back(a);
    if (sa <= 0.0) out.push_back(a);
    if ((sa > 0.0 && sb < 0.0) || (sa < 0.0 && sb > 0.0)) {
      const glm::dvec3 x = a + (b - a) * (sa / (sa - sb));
      in.push_back(x);
      out.push_back(x);
    }
  }
}

bool in_triangle(const std::array<glm::dvec2, 3>& q, const glm::dvec2& x, glm::dvec3& w) {
  const double d = (q[1].y - q[2].y) * (q[0].x - q[2].x) + (q[2].x - q[1].x) * (q[0].y - q[2].y);
  if (d == 0.0) return false;
  w.x = ((q[1].y - q[2].y) * (x.x - q[2].x) + (q[2].x - q[1].x) * (x.y - q[2].y)) / d;
  w.y = ((q[2].y - q[0].y) * (x.x - q[2].x) + (q[0].x - q[2].x) * (x.y - q[2].y)) / d;
  w.z = 1.0 - w.x - w.y;
  return w.x >= 0.0 && w.y >= 0.0 && w.z >= 0.0;
}

}  // namespace sirad
