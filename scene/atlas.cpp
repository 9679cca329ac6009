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

// The most texels the file's faces' UV bounds may hold in all (each is rasterised over its
// bounds), per texel of the square (a layout whose islands do not overlap holds about 2: a
// triangle's bounds are twice its area) and per face (its bounds' rim).
constexpr double kMaxFileBoundsPerTexel = 8, kMaxFileBoundsPerFace = 16;

// An edge that more faces than this share (a fan of coincident faces, a hostile file) joins no
// chart and is no seam: each face it has looks at the others, so this bounds that work.
constexpr std::size_t kMaxEdgeFaces = 16;

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
// float positions, at most kMaxEdgeFaces faces) within kChartAngleDegrees of the chart's first
// face, where the edge is not along a contact segment of either face (a wall's foot). Each
// chart's triangles in scene order.
// The faces' shared edges: each corner's vertex (its float position), and per edge (its two
// vertices, lower first) the faces that have it; with each face's contact segments.
struct Edges {
  std::vector<std::array<uint32_t, 3>> ids;
  std::map<std::pair<uint32_t, uint32_t>, std::vector<uint32_t>> faces;
  std::vector<glm::dvec3> position;
  std::vector<std::vector<ContactSegment>> contacts;
  double tolerance = 0;  // how near a contact segment an edge lies along it

  explicit Edges(const Scene& scene)
      : ids(scene.triangles.size()), contacts(contact_segments(scene, contact_tolerance(scene))), tolerance(10 * contact_tolerance(scene)) {
    std::map<std::array<float, 3>, uint32_t> vertex_id;
    for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
      for (std::size_t k = 0; k < 3; ++k) {
        const glm::vec3& p = scene.triangles[i].p[k];
        ids[i][k] = vertex_id.emplace(std::array<float, 3>{p.x, p.y, p.z}, static_cast<uint32_t>(vertex_id.size())).first->second;
      }
      for (std::size_t k = 0; k < 3; ++k) {
        const uint32_t a = ids[i][k], b = ids[i][(k + 1) % 3];
        faces[{std::min(a, b), std::max(a, b)}].push_back(static_cast<uint32_t>(i));
      }
    }
    position.resize(vertex_id.size());
    for (const auto& [p, id] : vertex_id) position[id] = glm::dvec3(p[0], p[1], p[2]);
  }

  // Whether edge (a, b) lies along a contact segment of face t or face f (a wall's foot).
  bool at_contact(uint32_t t, uint32_t f, uint32_t a, uint32_t b) const {
    return along(contacts[t], position[a], position[b], tolerance) || along(contacts[f], position[a], position[b], tolerance);
  }
};

std::vector<std::vector<uint32_t>> find_charts(const Scene& scene, const std::vector<glm::dvec3>& normal, Edges& e) {
  const std::size_t n = scene.triangles.size();
  const auto& ids = e.ids;
  const auto& position = e.position;
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
        const std::vector<uint32_t>& sharing = e.faces[{std::min(a, b), std::max(a, b)}];
        if (sharing.size() > kMaxEdgeFaces) continue;
        for (const uint32_t f : sharing) {
          if (taken[f] || !fits(f) || e.at_contact(t, f, a, b)) continue;
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
// With fixed_width > 0, the shelves are that wide (or as wide as the widest chart).
bool pack(std::vector<Chart>& charts, const std::vector<Frame>& frames, double texel, const AtlasOptions& o, int& width,
          int& height, int fixed_width = 0) {
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
  width = std::max(widest, fixed_width > 0 ? fixed_width : static_cast<int>(std::ceil(std::sqrt(texels))));
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
  return width > 0 && height > 0 ? static_cast<double>(face_texels) / (double(width) * height) : 0.0;
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

namespace {

// Sirad's charts of the triangles `groups` holds, packed at `texel` (fixed_width as pack's), with
// their corners' UV in texels (atlas.uv, over the atlas's size later) and their texels' owners.
bool place_own(const Scene& scene, const std::vector<std::vector<uint32_t>>& groups, const std::vector<glm::dvec3>& normal,
               const std::vector<double>& area, double texel, const AtlasOptions& o, int fixed_width, std::vector<Chart>& charts,
               int& width, int& height) {
  std::vector<Frame> frames;
  charts.clear();
  for (const auto& g : groups) {
    frames.push_back(chart_frame(scene, g, normal, area));
    Chart c;
    c.triangles = g;
    c.origin = frames.back().origin, c.u = frames.back().u, c.v = frames.back().v, c.normal = frames.back().normal;
    c.texel = texel;
    charts.push_back(std::move(c));
  }
  return texel > 0 && pack(charts, frames, texel, o, width, height, fixed_width);
}

// Each corner of sirad's charts at its place in its chart's frame, in texels.
void own_uv(const Scene& scene, const std::vector<Chart>& charts, int gutter, std::vector<std::array<glm::dvec2, 3>>& uv) {
  for (const Chart& ch : charts)
    for (uint32_t t : ch.triangles)
      for (int k = 0; k < 3; ++k) {
        const glm::dvec3 d = corner(scene.triangles[t], k) - ch.origin;
        uv[t][static_cast<std::size_t>(k)] = {ch.x + gutter + glm::dot(d, ch.u) / ch.texel, ch.y + gutter + glm::dot(d, ch.v) / ch.texel};
      }
}

// The file's charts: its placed faces joined by corners at the same place with the same UV.
std::vector<std::vector<uint32_t>> file_charts(const Scene& scene, const std::vector<uint8_t>& placed,
                                               const std::vector<std::array<glm::dvec2, 3>>& uv) {
  const std::size_t n = scene.triangles.size();
  std::vector<uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  const auto root = [&](uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  std::map<std::array<float, 5>, uint32_t> first;
  for (uint32_t i = 0; i < n; ++i) {
    if (!placed[i]) continue;
    for (std::size_t k = 0; k < 3; ++k) {
      const glm::vec3& p = scene.triangles[i].p[k];
      const std::array<float, 5> key = {p.x, p.y, p.z, static_cast<float>(uv[i][k].x), static_cast<float>(uv[i][k].y)};
      const auto [it, added] = first.emplace(key, i);
      if (!added) {
        const uint32_t a = root(i), b = root(it->second);
        parent[std::max(a, b)] = std::min(a, b);
      }
    }
  }
  std::vector<std::vector<uint32_t>> charts;
  std::vector<uint32_t> chart_of_root(n, kNoChart);
  for (uint32_t i = 0; i < n; ++i) {
    if (!placed[i]) continue;
    uint32_t& c = chart_of_root[root(i)];
    if (c == kNoChart) c = static_cast<uint32_t>(charts.size()), charts.emplace_back();
    charts[c].push_back(i);
  }
  return charts;
}

// The owners of the file's sw x sh texels (Atlas::owner, `width` wide): each texel the
// chart whose faces hold its centre, else the one that covers most of its 4 x 4 points, then
// `gutter` rings around them. Returns the
// texels of the faces; counts in `shared` those that a second chart covers 4 points of.
std::size_t own_file_texels(const std::vector<std::vector<uint32_t>>& charts, const std::vector<std::array<glm::dvec2, 3>>& uv, int sw,
                            int sh, int width, int gutter, std::vector<uint32_t>& owner, std::size_t& shared) {
  const std::size_t texels = static_cast<std::size_t>(sw) * static_cast<std::size_t>(sh);
  std::vector<uint16_t> best(texels, 0), here(texels, 0);
  std::vector<uint8_t> contested(texels, 0);
  std::vector<uint32_t> touched;
  for (std::size_t c = 0; c < charts.size(); ++c) {
    touched.clear();
    for (uint32_t t : charts[c]) {
      std::array<glm::dvec2, 3> q;
      for (std::size_t k = 0; k < 3; ++k) q[k] = uv[t][k] * glm::dvec2(sw, sh);
      const glm::dvec2 lo = glm::min(q[0], glm::min(q[1], q[2])), hi = glm::max(q[0], glm::max(q[1], q[2]));
      const int x0 = std::clamp(static_cast<int>(std::floor(lo.x)), 0, sw - 1), x1 = std::clamp(static_cast<int>(std::floor(hi.x)), 0, sw - 1);
      const int y0 = std::clamp(static_cast<int>(std::floor(lo.y)), 0, sh - 1), y1 = std::clamp(static_cast<int>(std::floor(hi.y)), 0, sh - 1);
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
          // A chart that holds the texel's centre comes first (as Cycles and engines' bakers
          // rasterise: where islands touch, the texel is the one its centre lies in), then the
          // count of its 16 points.
          int count = 0;
          glm::dvec3 w;
          for (int s = 0; s < 16; ++s) count += in_triangle(q, {x + (s % 4 + 0.5) / 4, y + (s / 4 + 0.5) / 4}, w);
          const bool centre = in_triangle(q, {x + 0.5, y + 0.5}, w);
          if (count == 0 && !centre) continue;
          const std::size_t k = static_cast<std::size_t>(y) * static_cast<std::size_t>(sw) + static_cast<std::size_t>(x);
          if (here[k] == 0) touched.push_back(static_cast<uint32_t>(k));
          // The score: 17 for the centre, and the points (at most 16 over the chart's faces).
          const int points = std::min(16, here[k] % 17 + count);
          here[k] = static_cast<uint16_t>((here[k] >= 17 || centre ? 17 : 0) + std::max(points, 1));
        }
    }
    for (uint32_t k : touched) {
      const std::size_t at = (k / static_cast<uint32_t>(sw)) * static_cast<std::size_t>(width) + k % static_cast<uint32_t>(sw);
      if (best[k] % 17 >= 4 && here[k] % 17 >= 4) contested[k] = 1;
      if (here[k] > best[k]) best[k] = here[k], owner[at] = static_cast<uint32_t>(c);
      here[k] = 0;
    }
  }
  std::size_t faces = 0;
  for (std::size_t k = 0; k < texels; ++k) faces += best[k] > 0, shared += contested[k];
  // The gutters: ring by ring, an empty texel next to (8-connected) a chart's takes the lowest.
  std::vector<std::pair<std::size_t, uint32_t>> ring;
  for (int r = 0; r < gutter; ++r) {
    ring.clear();
    for (int y = 0; y < sh; ++y)
      for (int x = 0; x < sw; ++x) {
        const std::size_t at = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
        if (owner[at] != kNoChart) continue;
        uint32_t c = kNoChart;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int a = x + dx, b = y + dy;
            if (a >= 0 && a < sw && b >= 0 && b < sh)
              c = std::min(c, owner[static_cast<std::size_t>(b) * static_cast<std::size_t>(width) + static_cast<std::size_t>(a)]);
          }
        if (c != kNoChart) ring.emplace_back(at, c);
      }
    if (ring.empty()) break;
    for (const auto& [at, c] : ring) owner[at] = c;
  }
  return faces;
}

}  // namespace

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

  // Step 2: the faces the file places (fronts with a UV map of some area, in the unit square),
  // their UV, and the UV area and surface they have.
  std::vector<std::array<glm::dvec2, 3>> uv(n);
  std::vector<uint8_t> placed(n, 0);
  double uv_area = 0, placed_area = 0;
  if (o.file_layout)
    for (std::size_t i = 0; i < n; ++i) {
      const Triangle& t = scene.triangles[i];
      if (t.back || t.uv_map >= scene.uv_maps.size() || !(area[i] > 0)) continue;
      bool in = true;
      for (std::size_t k = 0; k < 3; ++k) {
        uv[i][k] = scene.uv_maps[t.uv_map].at(corner(t, static_cast<int>(k)));
        in = in && uv[i][k].x >= -1e-6 && uv[i][k].x <= 1 + 1e-6 && uv[i][k].y >= -1e-6 && uv[i][k].y <= 1 + 1e-6;
      }
      const double a = 0.5 * std::abs(cross2(uv[i][0], uv[i][1], uv[i][2]));
      if (!in || !(a > 0)) continue;
      placed[i] = 1, uv_area += a, placed_area += area[i];
    }
  const bool file = placed_area > 0;

  // Step 3: sirad's charts (of the faces the file does not place).
  Atlas atlas;
  atlas.gutter = o.gutter;
  Edges edges(scene);
  std::vector<std::vector<uint32_t>> groups = find_charts(scene, normal, edges);
  if (file) {
    for (auto& g : groups) std::erase_if(g, [&](uint32_t t) { return placed[t] != 0; });
    std::erase_if(groups, [](const std::vector<uint32_t>& g) { return g.empty(); });
  }

  // Step 4: the texel size (given, or grown from the budget's until the atlas fits) and the
  // packing: the file's UV square at sw x sh texels (the size the file names, unless a texel
  // size is given; else from the texel size, in the named size's proportions or square) with
  // sirad's charts below it.
  double texel = o.texel_size > 0 ? o.texel_size : std::sqrt(total / static_cast<double>(o.texel_budget));
  const bool named = file && scene.lightmap_size.has_value();
  const double aspect = named ? double((*scene.lightmap_size)[0]) / (*scene.lightmap_size)[1] : 1.0;
  int sw = 0, sh = 0;
  // The file's mean texel at sw x sh.
  const auto file_texel = [&] { return std::sqrt(placed_area / (uv_area * sw * sh)); };
  for (int tries = 0;; ++tries) {
    bool fits = texel > 0;
    if (fits && file) {
      double w = 0, h = 0;
      if (named && o.texel_size == 0 && tries == 0) {
        w = (*scene.lightmap_size)[0], h = (*scene.lightmap_size)[1];
      } else {
        h = std::max(4.0, std::ceil(std::sqrt(placed_area / (uv_area * aspect)) / texel / 4) * 4);
        w = std::max(4.0, std::ceil(h * aspect / 4) * 4);
      }
      fits = w <= o.max_side && h <= o.max_side;
      sw = fits ? static_cast<int>(w) : 0, sh = fits ? static_cast<int>(h) : 0;
    }
    int band_width = 0, band_height = 0;
    if (fits && !groups.empty()) {
      const double own = file ? file_texel() : texel;
      AtlasOptions below = o;
      below.max_side = o.max_side - sh;
      fits = below.max_side >= 1 && place_own(scene, groups, normal, area, own, below, sw, atlas.charts, band_width, band_height);
    }
    if (fits) {
      atlas.width = std::max(sw, band_width), atlas.height = sh + band_height;
      fits = atlas.width <= o.max_side && atlas.height <= o.max_side;
    }
    if (fits) break;
    if (o.texel_size > 0)
      fail("atlas: texels of {:.6g} make an atlas of more than {} x {} texels for {} ({:.4g} of surface); larger texels "
           "are needed",
           o.texel_size, o.max_side, o.max_side, scene.name, total);
    if (tries == kMaxTries) fail("atlas: {} does not fit an atlas of {} x {} texels", scene.name, o.max_side, o.max_side);
    texel = texel > 0 ? texel * kGrow : extent / o.max_side;
  }
  if (file) {
    // The file's faces are rasterised over their bounds (and the bake indexes them so): bounded
    // whatever the file's UV says (islands laid over each other, slivers across the square).
    double bounds = 0, most = double(sw) * sh * kMaxFileBoundsPerTexel;
    for (std::size_t i = 0; i < n; ++i)
      if (placed[i]) {
        most += kMaxFileBoundsPerFace;
        const glm::dvec2 a = glm::min(uv[i][0], glm::min(uv[i][1], uv[i][2])), b = glm::max(uv[i][0], glm::max(uv[i][1], uv[i][2]));
        bounds += (std::floor(b.x * sw) - std::floor(a.x * sw) + 1) * (std::floor(b.y * sh) - std::floor(a.y * sh) + 1);
      }
    if (bounds > most)
      fail("atlas: {}: the faces of its TEXCOORD_1 span {:.3g} texels in their bounds at {} x {} (more than {:.3g}: islands laid "
           "over each other, or slivers across the square); --own-atlas lays the lightmap out in sirad's charts",
           scene.name, bounds, sw, sh, most);
  }
  atlas.texel_size = file ? file_texel() : texel;
  atlas.file_width = sw, atlas.file_height = sh;
  atlas.owner.assign(static_cast<std::size_t>(atlas.width) * static_cast<std::size_t>(atlas.height), kNoChart);

  // Step 5: sirad's charts' UV (in texels) and texels, below the file's square.
  for (Chart& ch : atlas.charts) {
    ch.y += sh;
    for (int y = ch.y; y < ch.y + ch.height; ++y)
      for (int x = ch.x; x < ch.x + ch.width; ++x) atlas.owner[static_cast<std::size_t>(y) * static_cast<std::size_t>(atlas.width) + static_cast<std::size_t>(x)] = static_cast<uint32_t>(&ch - atlas.charts.data());
    atlas.face_texels += static_cast<std::size_t>(ch.width - 2 * o.gutter) * static_cast<std::size_t>(ch.height - 2 * o.gutter);
  }
  own_uv(scene, atlas.charts, o.gutter, uv);

  // Step 6: the file's charts, after sirad's: their texels, and their UV in texels.
  if (file) {
    const std::size_t first = atlas.charts.size();
    const std::vector<std::vector<uint32_t>> islands = file_charts(scene, placed, uv);
    std::vector<uint32_t> owner(static_cast<std::size_t>(atlas.width) * static_cast<std::size_t>(sh), kNoChart);
    atlas.face_texels += own_file_texels(islands, uv, sw, sh, atlas.width, o.gutter, owner, atlas.shared_texels);
    for (std::size_t k = 0; k < owner.size(); ++k)
      if (owner[k] != kNoChart) atlas.owner[k] = static_cast<uint32_t>(first + owner[k]);
    std::vector<std::array<int, 4>> bounds(islands.size(), {sw, sh, -1, -1});
    for (int y = 0; y < sh; ++y)
      for (int x = 0; x < sw; ++x)
        if (const uint32_t c = owner[static_cast<std::size_t>(y) * static_cast<std::size_t>(atlas.width) + static_cast<std::size_t>(x)]; c != kNoChart) {
          auto& b = bounds[c];
          b = {std::min(b[0], x), std::min(b[1], y), std::max(b[2], x), std::max(b[3], y)};
        }
    for (std::size_t c = 0; c < islands.size(); ++c) {
      Chart ch;
      ch.triangles = islands[c];
      ch.flat = false;
      double a_uv = 0, a = 0;
      for (uint32_t t : ch.triangles) {
        ch.normal += normal[t] * area[t], a += area[t];
        a_uv += 0.5 * std::abs(cross2(uv[t][0], uv[t][1], uv[t][2]));
        for (auto& q : uv[t]) q *= glm::dvec2(sw, sh);
      }
      ch.normal = glm::length(ch.normal) > 0 ? glm::normalize(ch.normal) : glm::dvec3(0, 0, 1);
      ch.texel = std::sqrt(a / (a_uv * sw * sh));
      const auto& b = bounds[c];
      if (b[2] >= 0) ch.x = b[0], ch.y = b[1], ch.width = b[2] - b[0] + 1, ch.height = b[3] - b[1] + 1;
      atlas.charts.push_back(std::move(ch));
    }
  }

  // Step 7: each corner's UV over the atlas's size.
  atlas.chart_of.assign(n, 0);
  atlas.uv.assign(n, {});
  for (std::size_t c = 0; c < atlas.charts.size(); ++c)
    for (uint32_t t : atlas.charts[c].triangles) {
      atlas.chart_of[t] = static_cast<uint32_t>(c);
      for (std::size_t k = 0; k < 3; ++k)
        atlas.uv[t][k] = glm::vec2(static_cast<float>(uv[t][k].x / atlas.width), static_cast<float>(uv[t][k].y / atlas.height));
    }

  // Step 8: the seams: edges where two faces are one surface (one material, within
  // kChartAngleDegrees, both in a gap or neither, not at a contact) but not one place in the
  // atlas (two charts, or two places of one).
  const double cos_bound = std::cos(kChartAngleDegrees * std::numbers::pi / 180.0);
  for (const auto& [edge, faces] : edges.faces)
    for (std::size_t x = 0; x < faces.size() && faces.size() <= kMaxEdgeFaces; ++x)
      for (std::size_t y = x + 1; y < faces.size(); ++y) {
        const uint32_t t = faces[x], f = faces[y];
        const Triangle &a = scene.triangles[t], &b = scene.triangles[f];
        if (a.material != b.material || a.in_gap != b.in_gap || !(glm::dot(normal[t], normal[f]) >= cos_bound) ||
            edges.at_contact(t, f, edge.first, edge.second))
          continue;
        Seam seam{.a = t, .b = f};
        for (std::size_t end = 0; end < 2; ++end) {
          const uint32_t v = end == 0 ? edge.first : edge.second;
          for (std::size_t k = 0; k < 3; ++k) {
            if (edges.ids[t][k] == v) seam.uv_a[end] = atlas.uv[t][k];
            if (edges.ids[f][k] == v) seam.uv_b[end] = atlas.uv[f][k];
          }
        }
        const auto apart = [&](const glm::vec2& p, const glm::vec2& q) {
          return std::abs(p.x - q.x) * atlas.width > 1e-3 || std::abs(p.y - q.y) * atlas.height > 1e-3;
        };
        if (atlas.chart_of[t] != atlas.chart_of[f] || apart(seam.uv_a[0], seam.uv_b[0]) || apart(seam.uv_a[1], seam.uv_b[1]))
          atlas.seams.push_back(seam);
      }
  return atlas;
}

}  // namespace sirad
