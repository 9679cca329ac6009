// sirad: a lightmap atlas of a scene (see atlas.h).
#include "scene/atlas.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>
#include <utility>

#include <glm/geometric.hpp>

#include "scene/contacts.h"
#include "util/error.h"
#include "util/polygon.h"

namespace sirad {

namespace {

// A chart grows from its first face across shared edges to faces whose normals are within
// kChartAngle of that first face's normal (not of the neighbour's: the bound does not accumulate
// along a curved surface) and whose corners lie within the same angle of its plane as seen from
// its first corner (a gently sloped ramp that winds back over itself stays two charts). A
// quad whose two triangles are not quite in one plane (the Cornell box's red wall, a face
// exported from a tolerance-free modeller) is then one chart: no seam across it. Projected
// onto the chart's plane, a face tilted by the angle loses at most 1 - cos 2 degrees (0.06 %)
// of its texels.
constexpr double kChartAngleDegrees = 2.0;

// From a budget, the texel size grows by this until the atlas fits max_side, at most this often.
constexpr double kGrow = 1.25;
constexpr int kMaxTries = 64;

glm::dvec3 corner(const Triangle& t, int k) { return glm::dvec3(t.p[static_cast<std::size_t>(k)]); }

// Whether the segment [a, b] lies along one of `segments`: both ends within `tolerance` of its
// line and its middle within the segment's length.
bool along(const std::vector<ContactSegment>& segments, const glm::dvec3& a, const glm::dvec3& b, double tolerance) {
  for (const ContactSegment& s : segments) {
    const glm::dvec3 d = s.q - s.p;
    const double length = glm::length(d);
    if (!(length > 0)) continue;
    const glm::dvec3 u = d / length;
    const auto off = [&](const glm::dvec3& x) { return glm::length((x - s.p) - u * glm::dot(x - s.p, u)); };
    const double mid = glm::dot(0.5 * (a + b) - s.p, u);
    if (off(a) <= tolerance && off(b) <= tolerance && mid >= -tolerance && mid <= length + tolerance) return true;
  }
  return false;
}

// The triangles' charts: those of one object grown across shared edges (corners at the same
// float positions) within kChartAngleDegrees of the chart's first face, where the edge is not
// along a contact segment of either face (a wall's foot). Each chart's triangles in scene order.
std::vector<std::vector<uint32_t>> find_charts(const Scene& scene, const std::vector<glm::dvec3>& normal) {
  const double tolerance = 10 * contact_tolerance(scene);
  const std::vector<std::vector<ContactSegment>> contacts = contact_segments(scene, contact_tolerance(scene));
  const std::size_t n = scene.triangles.size();
  std::map<std::array<float, 3>, uint32_t> vertex_id;
  std::vector<std::array<uint32_t, 3>> ids(n);
  std::map<std::pair<uint32_t, uint32_t>, std::vector<uint32_t>> edges;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t k = 0; k < 3; ++k) {
      const glm::vec3& p = scene.triangles[i].p[k];
      ids[i][k] = vertex_id.emplace(std::array<float, 3>{p.x, p.y, p.z}, static_cast<uint32_t>(vertex_id.size())).first->second;
    }
    for (std::size_t k = 0; k < 3; ++k) {
      const uint32_t a = ids[i][k], b = ids[i][(k + 1) % 3];
      edges[{std::min(a, b), std::max(a, b)}].push_back(static_cast<uint32_t>(i));
    }
  }
  std::vector<glm::dvec3> position(vertex_id.size());
  for (const auto& [p, id] : vertex_id) position[id] = glm::dvec3(p[0], p[1], p[2]);
  const double cos_bound = std::cos(kChartAngleDegrees * std::numbers::pi / 180.0);
  const double sin_bound = std::sin(kChartAngleDegrees * std::numbers::pi / 180.0);
  std::vector<std::vector<uint32_t>> charts;
  std::vector<bool> taken(n, false);
  std::vector<uint32_t> queue;
  for (uint32_t seed = 0; seed < n; ++seed) {
    if (taken[seed]) continue;
    const Triangle& first = scene.triangles[seed];
    const glm::dvec3 up = normal[seed], origin = corner(first, 0);
    // Whether face f may join the chart grown from `seed`.
    const auto fits = [&](uint32_t f) {
      if (scene.triangles[f].object != first.object || !(glm::dot(up, normal[f]) >= cos_bound)) return false;
      for (int k = 0; k < 3; ++k) {
        const glm::dvec3 d = corner(scene.triangles[f], k) - origin;
        if (std::abs(glm::dot(up, d)) > sin_bound * glm::length(d)) return false;
      }
      return true;
    };
    taken[seed] = true;
    charts.emplace_back(1, seed);
    queue.assign(1, seed);
    while (!queue.empty()) {
      const uint32_t t = queue.back();
      queue.pop_back();
      for (std::size_t k = 0; k < 3; ++k) {
        const uint32_t a = ids[t][k], b = ids[t][(k + 1) % 3];
        for (const uint32_t f : edges[{std::min(a, b), std::max(a, b)}]) {
          if (taken[f] || !fits(f) || along(contacts[t], position[a], position[b], tolerance) ||
              along(contacts[f], position[a], position[b], tolerance))
            continue;
          taken[f] = true;
          charts.back().push_back(f);
          queue.push_back(f);
        }
      }
    }
    std::sort(charts.back().begin(), charts.back().end());
  }
  return charts;
}

double cross2(const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
  return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

// The convex hull of `p` (Andrew's monotone chain), counter-clockwise, no point repeated.
std::vector<glm::dvec2> hull(std::vector<glm::dvec2> p) {
  std::sort(p.begin(), p.end(), [](const glm::dvec2& a, const glm::dvec2& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  p.erase(std::unique(p.begin(), p.end()), p.end());
  if (p.size() < 3) return p;
  std::vector<glm::dvec2> h(2 * p.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross2(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross2(h[k - 2], h[k - 1], p[i - 1]) <= 0) --k;
    h[k++] = p[i - 1];
  }
  h.resize(k - 1);
  return h;
}

// A chart's plane frame, turned to its least bounding rectangle (each hull edge's direction
// tried: the least rectangle has a side on one), with the rectangle's extents in scene units.
struct Frame {
  glm::dvec3 origin, u, v, normal;
  double extent_u = 0, extent_v = 0;
};

Frame chart_frame(const Scene& scene, const std::vector<uint32_t>& tris, const std::vector<glm::dvec3>& normal,
                  const std::vector<double>& area) {
  glm::dvec3 n(0.0);
  for (uint32_t t : tris) n += normal[t] * area[t];
  n = glm::length(n) > 0 ? glm::normalize(n) : glm::dvec3(0, 0, 1);
  const glm::dvec3 o = corner(scene.triangles[tris[0]], 0);
  const glm::dvec3 helper = std::abs(n.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  const glm::dvec3 e1 = glm::normalize(glm::cross(helper, n)), e2 = glm::cross(n, e1);
  std::vector<glm::dvec2> flat;
  for (uint32_t t : tris)
    for (int k = 0; k < 3; ++k) {
      const glm::dvec3 d = corner(scene.triangles[t], k) - o;
      flat.push_back({glm::dot(d, e1), glm::dot(d, e2)});
    }
  const std::vector<glm::dvec2> h = hull(flat);
  glm::dvec2 best_dir(1, 0);
  double best = INFINITY;
  for (std::size_t i = 0; i < h.size(); ++i) {
    const glm::dvec2 edge = h[(i + 1) % h.size()] - h[i];
    if (!(glm::length(edge) > 0)) continue;
    const glm::dvec2 d = glm::normalize(edge), e(-d.y, d.x);
    double lo_u = INFINITY, hi_u = -INFINITY, lo_v = INFINITY, hi_v = -INFINITY;
    for (const glm::dvec2& q : h) {
      lo_u = std::min(lo_u, glm::dot(q, d)), hi_u = std::max(hi_u, glm::dot(q, d));
      lo_v = std::min(lo_v, glm::dot(q, e)), hi_v = std::max(hi_v, glm::dot(q, e));
    }
    if ((hi_u - lo_u) * (hi_v - lo_v) < best) best = (hi_u - lo_u) * (hi_v - lo_v), best_dir = d;
  }
  Frame f;
  f.normal = n;
  f.u = e1 * best_dir.x + e2 * best_dir.y;
  f.v = glm::cross(n, f.u);
  double lo_u = INFINITY, hi_u = -INFINITY, lo_v = INFINITY, hi_v = -INFINITY;
  for (uint32_t t : tris)
    for (int k = 0; k < 3; ++k) {
      const glm::dvec3 d = corner(scene.triangles[t], k) - o;
      lo_u = std::min(lo_u, glm::dot(d, f.u)), hi_u = std::max(hi_u, glm::dot(d, f.u));
      lo_v = std::min(lo_v, glm::dot(d, f.v)), hi_v = std::max(hi_v, glm::dot(d, f.v));
    }
  f.origin = o + f.u * lo_u + f.v * lo_v;
  f.extent_u = hi_u - lo_u;
  f.extent_v = hi_v - lo_v;
  return f;
}

// The charts' rectangles at `texel` packed in shelves, tallest first, into a width near the
// square root of their area; false when a side passes max_side.
bool pack(std::vector<Chart>& charts, const std::vector<Frame>& frames, double texel, const AtlasOptions& o, int& width,
          int& height) {
  double texels = 0;
  for (std::size_t c = 0; c < charts.size(); ++c) {
    const double w = std::ceil(frames[c].extent_u / texel) + 2.0 * o.gutter, h = std::ceil(frames[c].extent_v / texel) + 2.0 * o.gutter;
    if (!(std::max(w, h) <= o.max_side)) return false;
    texels += std::max(w, 1.0 + 2 * o.gutter) * std::max(h, 1.0 + 2 * o.gutter);
    if (texels > double(o.max_side) * o.max_side) return false;
    charts[c].width = static_cast<int>(std::max(w, 1.0 + 2 * o.gutter));
    charts[c].height = static_cast<int>(std::max(h, 1.0 + 2 * o.gutter));
  }
  std::vector<std::size_t> order(charts.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return charts[a].height > charts[b].height || (charts[a].height == charts[b].height && charts[a].width > charts[b].width);
  });
  int widest = 0;
  for (const Chart& c : charts) widest = std::max(widest, c.width);
  width = std::max(widest, static_cast<int>(std::ceil(std::sqrt(texels))));
  int x = 0, y = 0, shelf = 0;
  for (std::size_t i : order) {
    Chart& c = charts[i];
    if (x + c.width > width) x = 0, y += shelf, shelf = 0;
    c.x = x, c.y = y;
    x += c.width;
    shelf = std::max(shelf, c.height);
    if (y + shelf > o.max_side) return false;
  }
  height = y + shelf;
  width = std::min((width + 3) / 4 * 4, o.max_side);  // whole blocks of 4 for texture compression
  height = std::min((height + 3) / 4 * 4, o.max_side);
  return true;
}

}  // namespace

double Atlas::fill() const {
  double used = 0;
  for (const Chart& c : charts) used += double(c.width - 2 * gutter) * (c.height - 2 * gutter);
  return width > 0 && height > 0 ? used / (double(width) * height) : 0.0;
}

Scene cut_at_contacts(const Scene& scene) {
  const std::vector<std::vector<ContactSegment>> contacts = contact_segments(scene, contact_tolerance(scene));
  Scene out = scene;
  out.triangles.clear();
  std::vector<std::vector<glm::dvec3>> pieces, next;
  std::vector<glm::dvec3> in, below;
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    const Triangle& t = scene.triangles[i];
    const std::array<glm::dvec3, 3> p = {corner(t, 0), corner(t, 1), corner(t, 2)};
    const glm::dvec3 c = glm::cross(p[1] - p[0], p[2] - p[0]);
    if (contacts[i].empty() || !(glm::length(c) > 0)) {
      out.triangles.push_back(t);
      continue;
    }
    const glm::dvec3 normal = glm::normalize(c);
    const double size = std::sqrt(glm::length(c));  // about an edge
    pieces.assign(1, {p[0], p[1], p[2]});
    for (const ContactSegment& seg : contacts[i]) {
      glm::dvec3 a = seg.p, b = seg.q;
      if (pieces.size() >= kMaxPiecesPerFace || !clip_to_triangle(p, normal, a, b) || !(glm::length(b - a) > 1e-6 * size)) continue;
      const glm::dvec3 m = glm::normalize(glm::cross(normal, b - a));
      next.clear();
      for (const auto& piece : pieces) {
        // A piece the segment's line crosses within it (not one it grazes: a cut along its edge).
        double over = 0.0, under = 0.0;
        for (const glm::dvec3& x : piece) over = std::max(over, glm::dot(x - a, m)), under = std::max(under, -glm::dot(x - a, m));
        glm::dvec3 pa = a, pb = b;
        std::array<glm::dvec3, 3> hull3{};
        bool crosses = std::min(over, under) > 1e-9 * size;
        if (crosses) {  // and the segment itself reaches into it (a wall's foot ends where the wall does)
          crosses = false;
          for (std::size_t k = 1; k + 1 < piece.size() && !crosses; ++k) {
            hull3 = {piece[0], piece[k], piece[k + 1]};
            glm::dvec3 qa = pa, qb = pb;
            crosses = clip_to_triangle(hull3, normal, qa, qb) && glm::length(qb - qa) > 1e-6 * size;
          }
        }
        if (!crosses) {
          next.push_back(piece);
          continue;
        }
        split_convex(piece, a, m, in, below);
        if (in.size() >= 3 && below.size() >= 3) next.push_back(in), next.push_back(below);
        else next.push_back(piece);
      }
      std::swap(pieces, next);
    }
    for (const auto& piece : pieces)
      for (std::size_t k = 1; k + 1 < piece.size(); ++k) {
        Triangle f = t;
        f.p = {glm::vec3(piece[0]), glm::vec3(piece[k]), glm::vec3(piece[k + 1])};
        const glm::dvec3 fc = glm::cross(glm::dvec3(f.p[1] - f.p[0]), glm::dvec3(f.p[2] - f.p[0]));
        if (glm::dot(fc, normal) > 0) out.triangles.push_back(f);  // slivers with no area in float dropped
      }
  }
  return out;
}

Atlas make_atlas(const Scene& scene, const AtlasOptions& o) {
  // Step 1: the options, and each triangle's normal and area.
  if (!(o.texel_size >= 0) || !std::isfinite(o.texel_size)) fail("atlas: texel size {} is not a finite length >= 0", o.texel_size);
  if (o.gutter < 0 || o.gutter > 64) fail("atlas: gutter {} is outside 0..64 texels", o.gutter);
  if (o.max_side < 16 || o.max_side > 16384) fail("atlas: largest side {} is outside 16..16384 texels", o.max_side);
  if (o.texel_size == 0 && (o.texel_budget < 1 || o.texel_budget > (uint64_t{1} << 28)))
    fail("atlas: texel budget {} is outside 1..2^28", o.texel_budget);
  if (scene.triangles.empty()) fail("atlas: {} has no faces", scene.name);
  const std::size_t n = scene.triangles.size();
  std::vector<glm::dvec3> normal(n);
  std::vector<double> area(n);
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  double total = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Triangle& t = scene.triangles[i];
    const glm::dvec3 c = glm::cross(corner(t, 1) - corner(t, 0), corner(t, 2) - corner(t, 0));
    area[i] = 0.5 * glm::length(c);
    normal[i] = area[i] > 0 ? c / (2 * area[i]) : glm::dvec3(0.0);
    total += area[i];
    for (int k = 0; k < 3; ++k) lo = glm::min(lo, corner(t, k)), hi = glm::max(hi, corner(t, k));
  }
  const double extent = glm::length(hi - lo);

  // Step 2: the charts and their frames.
  Atlas atlas;
  atlas.gutter = o.gutter;
  const std::vector<std::vector<uint32_t>> groups = find_charts(scene, normal);
  std::vector<Frame> frames;
  for (const auto& g : groups) {
    frames.push_back(chart_frame(scene, g, normal, area));
    Chart c;
    c.triangles = g;
    c.origin = frames.back().origin, c.u = frames.back().u, c.v = frames.back().v, c.normal = frames.back().normal;
    atlas.charts.push_back(std::move(c));
  }

  // Step 3: the texel size (given, or grown from the budget's until the atlas fits) and the packing.
  double texel = o.texel_size > 0 ? o.texel_size : std::sqrt(total / static_cast<double>(o.texel_budget));
  for (int tries = 0;; ++tries) {
    if (texel > 0 && pack(atlas.charts, frames, texel, o, atlas.width, atlas.height)) break;
    if (o.texel_size > 0)
      fail("atlas: texels of {:.6g} make an atlas of more than {} x {} texels for {} ({:.4g} of surface); larger texels "
           "are needed",
           o.texel_size, o.max_side, o.max_side, scene.name, total);
    if (tries == kMaxTries) fail("atlas: {} does not fit an atlas of {} x {} texels", scene.name, o.max_side, o.max_side);
    texel = texel > 0 ? texel * kGrow : extent / o.max_side;
  }
  atlas.texel_size = texel;

  // Step 4: each corner's UV: its place in its chart's frame, in texels, over the atlas's size.
  atlas.chart_of.assign(n, 0);
  atlas.uv.assign(n, {});
  for (std::size_t c = 0; c < atlas.charts.size(); ++c) {
    const Chart& ch = atlas.charts[c];
    for (uint32_t t : ch.triangles) {
      atlas.chart_of[t] = static_cast<uint32_t>(c);
      for (int k = 0; k < 3; ++k) {
        const glm::dvec3 d = corner(scene.triangles[t], k) - ch.origin;
        const double x = ch.x + o.gutter + glm::dot(d, ch.u) / texel, y = ch.y + o.gutter + glm::dot(d, ch.v) / texel;
        atlas.uv[t][static_cast<std::size_t>(k)] = glm::vec2(static_cast<float>(x / atlas.width), static_cast<float>(y / atlas.height));
      }
    }
  }
  return atlas;
}

}  // namespace sirad
