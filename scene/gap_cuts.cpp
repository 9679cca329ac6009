// sirad: faces cut along the outline of a surface that nearly touches them, an emitter or any
// other (scene/scene.h cut_along_gaps; DESIGN.md section 1, "Light in gaps").
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <vector>

#include <glm/geometric.hpp>

#include "scene/contacts.h"
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

// A surface as the cuts see it: its outline, its normal, and the box within its reach.
struct Outline {
  Poly p;  // a convex outline, counter-clockwise seen from the front
  glm::dvec3 n;
  double extent;  // the outline's longest extent
  double reach;   // the largest gap cut for: kGapCut (an emitter) or kGapCutSurface x its extent
  bool emits;     // an emitter's (an emitter's back is a surface like any other)
  std::size_t first;  // its first triangle: of two faces at one place facing one way, the later is on top
  glm::dvec3 lo, hi;
};

constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();

// Surfaces as outlines, and each of their triangles' outline (kNone: none).
struct Outlines {
  std::vector<Outline> outlines;
  std::vector<std::size_t> outline_of;
};

// The emitting triangles (`emitting`), or all triangles, grouped: one material, one plane (normals
// within 1e-4 rad, offsets within 1e-6 of their extent), joined where they share a corner. A group
// that fills its convex hull (a panel of two triangles, a disc cut into a fan, a wardrobe's back)
// is one outline. Else, of the emitters each triangle is one; of all triangles, a group of one
// triangle is one and a larger group none (a wall with a door cut by a Boolean: its triangles'
// edges are no outline). Emitters: none when the scene has more pairs of emitting and other
// triangles than kMaxGapCutPairs.
Outlines surface_outlines(const Scene& scene, bool emitting) {
  std::vector<std::size_t> faces;  // the triangles grouped
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    const Triangle& t = scene.triangles[i];
    if (emitting && !scene.materials[t.material].emits()) continue;
    if (!(glm::length(glm::cross(glm::dvec3(t.p[1] - t.p[0]), glm::dvec3(t.p[2] - t.p[0]))) > 0.0)) continue;
    faces.push_back(i);
  }
  if (faces.empty()) return {};
  if (emitting && static_cast<double>(faces.size()) * static_cast<double>(scene.triangles.size()) > kMaxGapCutPairs) return {};
  auto normal_of = [&](std::size_t i) {
    const Triangle& t = scene.triangles[i];
    return glm::normalize(glm::cross(glm::dvec3(t.p[1] - t.p[0]), glm::dvec3(t.p[2] - t.p[0])));
  };
  std::vector<std::size_t> parent(faces.size());
  for (std::size_t a = 0; a < parent.size(); ++a) parent[a] = a;
  auto find = [&](std::size_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  {
    std::map<std::array<float, 3>, std::vector<std::size_t>> at;  // corner -> faces there (a few each)
    for (std::size_t a = 0; a < faces.size(); ++a)
      for (const glm::vec3& q : scene.triangles[faces[a]].p) {
        std::vector<std::size_t>& here = at[{q.x, q.y, q.z}];
        const glm::dvec3 na = normal_of(faces[a]);
        for (std::size_t b : here) {
          const Triangle &ta = scene.triangles[faces[a]], &tb = scene.triangles[faces[b]];
          if (ta.material != tb.material || !(glm::dot(na, normal_of(faces[b])) > 1.0 - 5e-9)) continue;
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
  for (std::size_t a = 0; a < faces.size(); ++a) groups[find(a)].push_back(faces[a]);
  Outlines out;
  std::vector<Outline>& outlines = out.outlines;
  std::vector<std::size_t>& outline_of = out.outline_of;
  outline_of.assign(scene.triangles.size(), kNone);
  auto add = [&](Poly outline, const glm::dvec3& n, bool emits, std::size_t first) {
    Outline em{std::move(outline), n, 0.0, 0.0, emits, first, glm::dvec3(std::numeric_limits<double>::infinity()), glm::dvec3(-std::numeric_limits<double>::infinity())};
    for (const glm::dvec3& a : em.p)
      for (const glm::dvec3& b : em.p) em.extent = std::max(em.extent, glm::length(b - a));
    em.reach = (emitting ? kGapCut : kGapCutSurface) * em.extent;  // an emitter's back: kGapCutSurface
    for (const glm::dvec3& a : em.p) em.lo = glm::min(em.lo, a), em.hi = glm::max(em.hi, a);
    em.lo -= glm::dvec3(em.reach);
    em.hi += glm::dvec3(em.reach);
    outlines.push_back(std::move(em));
  };
  for (const auto& [root, members] : groups) {
    const glm::dvec3 n = normal_of(members[0]);
    const bool emits = scene.materials[scene.triangles[members[0]].material].emits();
    Poly outline = members.size() > 1 ? convex_outline(scene.triangles, members, n) : Poly{};
    if (!outline.empty() && outline.size() <= 256) {
      add(std::move(outline), n, emits, *std::min_element(members.begin(), members.end()));
      for (std::size_t i : members) outline_of[i] = outlines.size() - 1;
      continue;
    }
    if (!emitting && members.size() > 1) continue;
    for (std::size_t i : members) {
      const Triangle& t = scene.triangles[i];
      add(Poly{glm::dvec3(t.p[0]), glm::dvec3(t.p[1]), glm::dvec3(t.p[2])}, normal_of(i), emits, i);
      outline_of[i] = outlines.size() - 1;
    }
  }
  return out;
}

// Each piece's marks: kOver, it lies over an outline (Triangle::in_gap); kStrip, it
// lies in a strip along the outline (Triangle::whole).
constexpr uint8_t kOver = 1, kStrip = 2;

// One face's pieces as the cuts along outlines leave them, with their marks.
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
  bool cut(const Outline& em, double gap, double offset, uint8_t set, uint8_t clear, double tiny, double least) {
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

// Outlines binned to a uniform grid over the scene's box by their boxes within reach, so that a
// face looks only at the outlines near it. An outline over more than kWide cells is looked at by
// every face instead. Queries count the outlines they hand out (`looked`).
class OutlineGrid {
 public:
  OutlineGrid(const std::vector<Outline>& outlines, const glm::dvec3& lo, const glm::dvec3& hi) : lo_(lo) {
    const std::size_t g = std::clamp<std::size_t>(static_cast<std::size_t>(std::cbrt(static_cast<double>(outlines.size()))), 1, 64);
    cells_ = glm::ivec3(static_cast<int>(g));
    size_ = glm::max((hi - lo) / static_cast<double>(g), glm::dvec3(1e-12));
    bins_.resize(g * g * g);
    seen_.assign(outlines.size(), 0);
    for (std::size_t k = 0; k < outlines.size(); ++k) {
      const glm::ivec3 a = cell(outlines[k].lo), b = cell(outlines[k].hi);
      const glm::ivec3 span = b - a + 1;
      if (static_cast<std::size_t>(span.x) * static_cast<std::size_t>(span.y) * static_cast<std::size_t>(span.z) > kWide) {
        wide_.push_back(k);
        continue;
      }
      for (int z = a.z; z <= b.z; ++z)
        for (int y = a.y; y <= b.y; ++y)
          for (int x = a.x; x <= b.x; ++x) bins_[index(x, y, z)].push_back(k);
    }
  }

  // Calls f(k) once for each outline whose box within reach may overlap [lo, hi], in ascending k.
  template <class F>
  void near(const glm::dvec3& lo, const glm::dvec3& hi, F&& f) {
    ++stamp_;
    found_.clear();
    auto take = [&](std::size_t k) {
      if (seen_[k] == stamp_) return;
      seen_[k] = stamp_;
      found_.push_back(k);
    };
    for (std::size_t k : wide_) take(k);
    const glm::ivec3 a = cell(lo), b = cell(hi);
    for (int z = a.z; z <= b.z; ++z)
      for (int y = a.y; y <= b.y; ++y)
        for (int x = a.x; x <= b.x; ++x)
          for (std::size_t k : bins_[index(x, y, z)]) take(k);
    std::sort(found_.begin(), found_.end());
    looked += static_cast<double>(found_.size());
    for (std::size_t k : found_) f(k);
  }

  double looked = 0.0;

 private:
  static constexpr std::size_t kWide = 4096;
  glm::ivec3 cell(const glm::dvec3& p) const {
    const glm::dvec3 c = glm::floor((p - lo_) / size_);
    return glm::clamp(glm::ivec3(glm::clamp(c, glm::dvec3(-1.0), glm::dvec3(1e6))), glm::ivec3(0), cells_ - 1);
  }
  std::size_t index(int x, int y, int z) const {
    return (static_cast<std::size_t>(z) * static_cast<std::size_t>(cells_.y) + static_cast<std::size_t>(y)) * static_cast<std::size_t>(cells_.x) +
           static_cast<std::size_t>(x);
  }
  glm::dvec3 lo_, size_;
  glm::ivec3 cells_;
  std::vector<std::vector<std::size_t>> bins_;
  std::vector<std::size_t> wide_, found_;
  std::vector<uint64_t> seen_;
  uint64_t stamp_ = 0;
};

}  // namespace

void cut_along_gaps(Scene& scene) {
  const Outlines lit = surface_outlines(scene, true);
  const std::vector<Outline>& emitters = lit.outlines;
  const std::vector<std::size_t>& emitter_of = lit.outline_of;
  const Outlines all = scene.triangles.size() <= kMaxSurfaceCutFaces ? surface_outlines(scene, false) : Outlines{};
  const std::vector<Outline>& others = all.outlines;
  if (emitters.empty() && others.empty()) return;
  glm::dvec3 scene_lo(std::numeric_limits<double>::infinity()), scene_hi(-std::numeric_limits<double>::infinity());
  for (const Triangle& t : scene.triangles)
    for (const glm::vec3& q : t.p) scene_lo = glm::min(scene_lo, glm::dvec3(q)), scene_hi = glm::max(scene_hi, glm::dvec3(q));
  OutlineGrid grid(others, scene_lo, scene_hi);
  const double coincident = contact_tolerance(scene);
  Cutter cutter;

  // Faces across a gap from an emitter: cut along its outline, and along the strips on both
  // sides of it where the gap is wide enough to matter. Faces across a gap from another surface,
  // facing it or its back: cut along its outline.
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
      const Outline& em = emitters[e];
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
    if (grid.looked <= kMaxGapCutPairs)
      grid.near(lo, hi, [&](std::size_t k) {
        const Outline& s = others[k];
        if (cutter.pieces_count() > kMaxPiecesPerFace) return;
        if (glm::any(glm::lessThan(hi, s.lo)) || glm::any(glm::greaterThan(lo, s.hi))) return;
        const double facing = glm::dot(n, s.n);
        if (!(std::abs(facing) > 0.9999)) return;  // parallel, its front or its back towards the face
        if (s.emits && facing < 0.0) return;        // an emitter's front: cut with its strips above
        // The surface lies in front of the face, further than the coincident-face rule's tie; or
        // within the tie, facing the same way and later, so on top of it (a rug laid on a floor).
        // (Within the tie and earlier, it is under the face, or the face's own surface.)
        const double gap = glm::dot(s.p[0] - a, n);
        const bool on_top = std::abs(gap) <= coincident && facing > 0.0 && s.first > i;
        if (!on_top && !(gap > coincident && gap <= s.reach)) return;
        // An outline edge that runs along one of the face's own edges (a wardrobe's back and the
        // wall both end at the floor) leaves, after float rounding, slivers up to about 1e-7 m wide
        // on either side: a part under 1e-6 of the face's double area stays with its neighbour.
        cutter.cut(s, facing < 0.0 ? gap : -gap, 0.0, kOver, 0, tiny, 1e-6 * glm::length(cr));
      });
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
    const Outline& em = emitters[e];
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
