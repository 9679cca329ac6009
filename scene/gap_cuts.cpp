// sirad: surfaces cut along the outline of an emitter that nearly touches them (scene/scene.h
// cut_near_emitters; DESIGN.md section 1, "Light in gaps").
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <vector>

#include <glm/geometric.hpp>

#include "scene/import.h"
#include "scene/scene.h"
#include "util/error.h"
#include "util/polygon.h"

namespace sirad {
namespace {

using Poly = std::vector<glm::dvec3>;

// A face is cut into at most about this many pieces, whatever the emitters over it.
constexpr std::size_t kMaxPiecesPerFace = 1024;

double area_of(const Poly& p) {
  glm::dvec3 s(0.0);
  for (std::size_t i = 1; i + 1 < p.size(); ++i) s += glm::cross(p[i] - p[0], p[i + 1] - p[0]);
  return 0.5 * glm::length(s);
}

// The convex outline (counter-clockwise seen from the front of normal n) of the triangles
// `members`, if they fill it to kSameArea: a lamp's cap that the exporter cut into a fan of
// slivers is cut along its rim only. Empty if they do not (a concave or broken group).
Poly convex_outline(const std::vector<Triangle>& triangles, const std::vector<std::size_t>& members, const glm::dvec3& n) {
  constexpr double kSameArea = 1e-6;
  std::vector<glm::dvec3> pts;
  double area = 0.0;
  for (std::size_t i : members) {
    const Triangle& t = triangles[i];
    for (const glm::vec3& q : t.p) pts.push_back(glm::dvec3(q));
    area += 0.5 * glm::length(glm::cross(glm::dvec3(t.p[1] - t.p[0]), glm::dvec3(t.p[2] - t.p[0])));
  }
  const glm::dvec3 o = pts[0];
  const glm::dvec3 u = glm::normalize(std::abs(n.x) < 0.9 ? glm::cross(n, glm::dvec3(1, 0, 0)) : glm::cross(n, glm::dvec3(0, 1, 0)));
  const glm::dvec3 w = glm::cross(n, u);  // (u, w, n) right-handed: counter-clockwise in (u, w) is seen from the front
  std::vector<glm::dvec2> q(pts.size());
  double extent = 0.0;
  for (std::size_t k = 0; k < pts.size(); ++k) {
    q[k] = {glm::dot(pts[k] - o, u), glm::dot(pts[k] - o, w)};
    extent = std::max(extent, glm::length(q[k]));
  }
  const std::vector<std::size_t> hull = convex_hull(q, 1e-9 * extent * extent);
  if (hull.size() < 3) return {};
  Poly out;
  double hull_area = 0.0;
  for (std::size_t i = 0; i < hull.size(); ++i) {
    out.push_back(pts[hull[i]]);
    const glm::dvec2 &a = q[hull[i]], &b = q[hull[(i + 1) % hull.size()]];
    hull_area += 0.5 * (a.x * b.y - b.x * a.y);
  }
  if (!(std::abs(hull_area - area) <= kSameArea * area)) return {};
  return out;
}

// An emitter as the cuts see it: its outline, its normal, and the box within its reach.
struct Emitter {
  Poly p;  // a convex outline, counter-clockwise seen from the front
  glm::dvec3 n;
  double extent;  // the outline's longest extent
  double reach;   // the largest gap cut for: kGapCut x its extent
  glm::dvec3 lo, hi;
};

constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();

// The scene's emitters as outlines, and each emitting triangle's outline (kNone: none).
struct Outlines {
  std::vector<Emitter> emitters;
  std::vector<std::size_t> emitter_of;
};

// Emitting triangles grouped: one material, one plane (normals within 1e-4 rad, offsets within
// 1e-6 of their extent), joined where they share a corner. A group that fills its convex hull
// (a panel of two triangles, a disc cut into a fan) is one outline; else each triangle is one.
// None when the scene has more pairs of emitting and other triangles than kMaxGapCutPairs.
Outlines emitter_outlines(const Scene& scene) {
  std::vector<std::size_t> lights;
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    const Triangle& t = scene.triangles[i];
    if (!scene.materials[t.material].emits()) continue;
    if (!(glm::length(glm::cross(glm::dvec3(t.p[1] - t.p[0]), glm::dvec3(t.p[2] - t.p[0]))) > 0.0)) continue;
    lights.push_back(i);
  }
  if (lights.empty()) return {};
  if (static_cast<double>(lights.size()) * static_cast<double>(scene.triangles.size()) > kMaxGapCutPairs) return {};
  auto normal_of = [&](std::size_t i) {
    const Triangle& t = scene.triangles[i];
    return glm::normalize(glm::cross(glm::dvec3(t.p[1] - t.p[0]), glm::dvec3(t.p[2] - t.p[0])));
  };
  std::vector<std::size_t> parent(lights.size());
  for (std::size_t a = 0; a < parent.size(); ++a) parent[a] = a;
  auto find = [&](std::size_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  {
    std::map<std::array<float, 3>, std::vector<std::size_t>> at;  // corner -> lights there (a few each)
    for (std::size_t a = 0; a < lights.size(); ++a)
      for (const glm::vec3& q : scene.triangles[lights[a]].p) {
        std::vector<std::size_t>& here = at[{q.x, q.y, q.z}];
        const glm::dvec3 na = normal_of(lights[a]);
        for (std::size_t b : here) {
          const Triangle &ta = scene.triangles[lights[a]], &tb = scene.triangles[lights[b]];
          if (ta.material != tb.material || !(glm::dot(na, normal_of(lights[b])) > 1.0 - 5e-9)) continue;
          double extent = 0.0;
          for (const glm::vec3& r : tb.p) extent = std::max(extent, glm::length(glm::dvec3(r - ta.p[0])));
          bool plane = true;
          for (const glm::vec3& r : tb.p) plane = plane && std::abs(glm::dot(na, glm::dvec3(r - ta.p[0]))) <= 1e-6 * extent + 1e-12;
          if (plane) parent[find(a)] = find(b);
        }
        if (here.size() < 16) here.push_back(a);
      }
  }
  std::map<std::size_t, std::vector<std::size_t>> groups;
  for (std::size_t a = 0; a < lights.size(); ++a) groups[find(a)].push_back(lights[a]);
  Outlines out;
  std::vector<Emitter>& emitters = out.emitters;
  std::vector<std::size_t>& emitter_of = out.emitter_of;
  emitter_of.assign(scene.triangles.size(), kNone);
  auto add = [&](Poly outline, const glm::dvec3& n) {
    Emitter em{std::move(outline), n, 0.0, 0.0, glm::dvec3(std::numeric_limits<double>::infinity()), glm::dvec3(-std::numeric_limits<double>::infinity())};
    for (const glm::dvec3& a : em.p)
      for (const glm::dvec3& b : em.p) em.extent = std::max(em.extent, glm::length(b - a));
    em.reach = kGapCut * em.extent;
    for (const glm::dvec3& a : em.p) em.lo = glm::min(em.lo, a), em.hi = glm::max(em.hi, a);
    em.lo -= glm::dvec3(em.reach);
    em.hi += glm::dvec3(em.reach);
    emitters.push_back(std::move(em));
  };
  for (const auto& [root, members] : groups) {
    const glm::dvec3 n = normal_of(members[0]);
    Poly outline = members.size() > 1 ? convex_outline(scene.triangles, members, n) : Poly{};
    if (!outline.empty() && outline.size() <= 256) {
      add(std::move(outline), n);
      for (std::size_t i : members) emitter_of[i] = emitters.size() - 1;
      continue;
    }
    for (std::size_t i : members) {
      const Triangle& t = scene.triangles[i];
      add(Poly{glm::dvec3(t.p[0]), glm::dvec3(t.p[1]), glm::dvec3(t.p[2])}, normal_of(i));
      emitter_of[i] = emitters.size() - 1;
    }
  }
  return out;
}

// Each piece's marks: kOver, it lies over an emitter's outline (Triangle::in_gap); kStrip, it
// lies in a strip along the outline (Triangle::whole).
constexpr uint8_t kOver = 1, kStrip = 2;

// One face's pieces as the cuts along emitters' outlines leave them, with their marks.
class Cutter {
 public:
  // Starts a face: one piece, with `marks`.
  void start(Poly piece, uint8_t marks) {
    pieces.assign(1, std::move(piece));
    over.assign(1, marks);
  }

  // Cuts `pieces` (convex, on a plane parallel to em's, `gap` from it along em.n) along em's
  // outline moved outward by `offset` (inward where negative: each edge's line moved, so the
  // corners are mitred). The marks of the pieces inside become (marks | set) & ~clear; the others
  // keep theirs. A cut that would leave a part of less than `least` area is not made: the part
  // stays with the larger side. Returns whether any piece lies partly or wholly inside.
  bool cut(const Emitter& em, double gap, double offset, uint8_t set, uint8_t clear, double tiny, double least) {
    std::swap(pending, pieces);
    std::swap(pending_over, over);
    pieces.clear();
    over.clear();
    bool overlaps = false;
    for (std::size_t p = 0; p < pending.size(); ++p) {
      const Poly& piece = pending[p];
      inside = piece;
      std::vector<Poly> outside;
      for (std::size_t k = 0; k < em.p.size() && !inside.empty(); ++k) {
        const glm::dvec3 q0 = em.p[k] + em.n * gap, q1 = em.p[(k + 1) % em.p.size()] + em.n * gap;
        const glm::dvec3 m = glm::normalize(glm::cross(em.n, q1 - q0));  // points into the outline
        split_convex(inside, q0 - m * offset, m, part_in, part_out);
        const double ai = part_in.size() >= 3 ? area_of(part_in) : 0.0, ao = part_out.size() >= 3 ? area_of(part_out) : 0.0;
        const double small = std::max(tiny, least);
        if (ao <= small && (least == 0.0 || ai > ao)) continue;  // wholly inside this edge
        if (ai <= small) {                                        // wholly outside
          inside.clear();
          break;
        }
        outside.push_back(part_out);
        inside = part_in;
      }
      overlaps = overlaps || !inside.empty();
      const uint8_t in_marks = static_cast<uint8_t>((pending_over[p] | set) & ~clear);
      if (inside.empty() || outside.empty()) {  // wholly outside, or wholly inside
        pieces.push_back(piece);
        over.push_back(inside.empty() ? pending_over[p] : in_marks);
        continue;
      }
      pieces.push_back(inside);
      over.push_back(in_marks);
      for (Poly& o : outside) {
        pieces.push_back(std::move(o));
        over.push_back(pending_over[p]);
      }
    }
    return overlaps;
  }

  // Appends triangle t's pieces as triangles (with their marks) to `into`, or t itself where
  // rounding left a piece not quite convex.
  void emit(const Triangle& t, const glm::dvec3& n, double tiny, const std::string& scene_name, std::vector<Triangle>& into) const {
    if (pieces.size() == 1) {
      Triangle u = t;
      u.in_gap = (over[0] & kOver) != 0;
      u.whole = (over[0] & kStrip) != 0;
      into.push_back(u);
      return;
    }
    const std::size_t start = into.size();
    for (std::size_t p = 0; p < pieces.size(); ++p) {
      std::vector<glm::vec3> corners(pieces[p].begin(), pieces[p].end());
      std::vector<std::array<uint32_t, 3>> tris;
      try {
        tris = triangulate_polygon(corners);
      } catch (const Error&) {
        into.resize(start);
        into.push_back(t);
        return;
      }
      for (const auto& k : tris) {
        Triangle u = t;
        u.p = {corners[k[0]], corners[k[1]], corners[k[2]]};
        u.in_gap = (over[p] & kOver) != 0;
        u.whole = (over[p] & kStrip) != 0;
        const glm::dvec3 uc = glm::cross(glm::dvec3(u.p[1] - u.p[0]), glm::dvec3(u.p[2] - u.p[0]));
        if (!(glm::length(uc) > tiny) || !(glm::dot(uc, n) > 0.0)) continue;  // a sliver of rounding
        into.push_back(u);
      }
    }
    if (into.size() > import::kMaxTriangles) fail("{}: more than {} triangles once cut along emitters", scene_name, import::kMaxTriangles);
  }

 std::size_t pieces_count() const { return pieces.size(); }

 private:
  std::vector<Poly> pending, pieces;
  std::vector<uint8_t> pending_over, over;
  Poly inside, part_in, part_out;
};

}  // namespace

void cut_near_emitters(Scene& scene) {
  const Outlines outlines = emitter_outlines(scene);
  const std::vector<Emitter>& emitters = outlines.emitters;
  const std::vector<std::size_t>& emitter_of = outlines.emitter_of;
  if (emitters.empty()) return;
  // Pairs looked at are bounded: a scene of very many emitters and faces is left uncut.
  if (static_cast<double>(emitters.size()) * static_cast<double>(scene.triangles.size()) > kMaxGapCutPairs) return;
  Cutter cutter;

  // Faces across a gap from an emitter: cut along its outline, and along the strips on both
  // sides of it where the gap is wide enough to matter.
  std::vector<double> nearest(emitters.size(), std::numeric_limits<double>::infinity());  // each emitter's narrowest gap
  std::vector<Triangle> out;
  out.reserve(scene.triangles.size());
  std::vector<std::pair<std::size_t, std::size_t>> emitting;  // (place in out, emitter)
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    const Triangle& t = scene.triangles[i];
    const glm::dvec3 a(t.p[0]), b(t.p[1]), c(t.p[2]);
    const glm::dvec3 cr = glm::cross(b - a, c - a);
    if (scene.materials[t.material].emits() || !(glm::length(cr) > 0.0)) {
      if (emitter_of[i] != kNone) emitting.emplace_back(out.size(), emitter_of[i]);
      out.push_back(t);
      continue;
    }
    const glm::dvec3 n = glm::normalize(cr);
    const glm::dvec3 lo = glm::min(a, glm::min(b, c)), hi = glm::max(a, glm::max(b, c));
    const double tiny = 1e-9 * glm::length(cr);
    cutter.start(Poly{a, b, c}, static_cast<uint8_t>((t.in_gap ? kOver : 0) | (t.whole ? kStrip : 0)));
    for (std::size_t e = 0; e < emitters.size(); ++e) {
      const Emitter& em = emitters[e];
      if (cutter.pieces_count() > kMaxPiecesPerFace) break;  // many emitters over one face: cut no further
      if (glm::any(glm::lessThan(hi, em.lo)) || glm::any(glm::greaterThan(lo, em.hi))) continue;
      if (!(glm::dot(n, em.n) < -0.9999)) continue;  // facing the emitter, parallel
      const double gap = glm::dot(a - em.p[0], em.n);
      if (!(gap > 0.0 && gap <= em.reach)) continue;
      if (!cutter.cut(em, gap, 0.0, kOver, 0, tiny, 0.0)) continue;  // not over the emitter
      nearest[e] = std::min(nearest[e], gap);
      if (gap < kGapStripsFrom * em.extent) continue;
      const double least = kGapStripLeast * gap * em.extent;
      cutter.cut(em, gap, kGapStripsOut.back() * gap, kStrip, 0, tiny, least);  // the strips' outer edge
      for (std::size_t k = 0; k + 1 < kGapStripsOut.size(); ++k) cutter.cut(em, gap, kGapStripsOut[k] * gap, 0, 0, tiny, least);
      for (std::size_t k = 0; k + 1 < kGapStripsIn.size(); ++k) cutter.cut(em, gap, -kGapStripsIn[k] * gap, 0, 0, tiny, least);
      cutter.cut(em, gap, -kGapStripsIn.back() * gap, 0, kStrip, tiny, least);  // their inner edge
    }
    cutter.emit(t, n, tiny, scene.name, out);
  }
  // The emitters' own strips along their rims, where a face lies across a gap from them.
  std::vector<Triangle> done;
  done.reserve(out.size());
  std::size_t next = 0;
  for (std::size_t j = 0; j < out.size(); ++j) {
    if (next == emitting.size() || emitting[next].first != j) {
      done.push_back(out[j]);
      continue;
    }
    const std::size_t e = emitting[next++].second;
    const Emitter& em = emitters[e];
    const double gap = nearest[e];  // infinite where no face lies across a gap from it
    const Triangle& t = out[j];
    if (!std::isfinite(gap) || gap < kGapStripsFrom * em.extent) {
      done.push_back(t);
      continue;
    }
    const glm::dvec3 a(t.p[0]), b(t.p[1]), c(t.p[2]);
    const glm::dvec3 cr = glm::cross(b - a, c - a);
    const double tiny = 1e-9 * glm::length(cr);
    cutter.start(Poly{a, b, c}, kStrip);
    // On the emitter's own plane (its outline is em.p, so the distance along its normal is ~0).
    const double on = glm::dot(a - em.p[0], em.n);
    const double least = kGapStripLeast * gap * em.extent;
    for (std::size_t k = 0; k + 1 < kGapStripsEmitter.size(); ++k) cutter.cut(em, on, -kGapStripsEmitter[k] * gap, 0, 0, tiny, least);
    cutter.cut(em, on, -kGapStripsEmitter.back() * gap, 0, kStrip, tiny, least);
    cutter.emit(t, glm::normalize(cr), tiny, scene.name, done);
  }
  scene.triangles = std::move(done);
}

}  // namespace sirad
