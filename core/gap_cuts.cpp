// sirad: surfaces cut along the outline of an emitter that nearly touches them (core/scene.h
// cut_near_emitters; DESIGN.md section 1, "Light in gaps").
#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <glm/geometric.hpp>

#include "core/error.h"
#include "core/polygon.h"
#include "core/scene.h"
#include "core/scene_import.h"

namespace sirad {
namespace {

using Poly = std::vector<glm::dvec3>;

// A face is cut into at most about this many pieces, whatever the emitters over it.
constexpr std::size_t kMaxPiecesPerFace = 1024;

bool emits(const Material& m) { return m.emission.x > 0.0f || m.emission.y > 0.0f || m.emission.z > 0.0f; }

double area_of(const Poly& p) {
  glm::dvec3 s(0.0);
  for (std::size_t i = 1; i + 1 < p.size(); ++i) s += glm::cross(p[i] - p[0], p[i + 1] - p[0]);
  return 0.5 * glm::length(s);
}

// Splits the convex polygon `p` by the plane dot(x - o, m) = 0 into the parts where it is >= 0
// (`in`) and <= 0 (`out`), corners kept in p's order.
void split(const Poly& p, const glm::dvec3& o, const glm::dvec3& m, Poly& in, Poly& out) {
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

}  // namespace

void cut_near_emitters(Scene& scene) {
  struct Emitter {
    std::array<glm::dvec3, 3> p;
    glm::dvec3 n;
    double reach;  // the largest gap cut for: kGapCut x its longest edge
    glm::dvec3 lo, hi;
  };
  std::vector<Emitter> emitters;
  for (const Triangle& t : scene.triangles) {
    if (!emits(scene.materials[t.material])) continue;
    Emitter em{{glm::dvec3(t.p[0]), glm::dvec3(t.p[1]), glm::dvec3(t.p[2])}, {}, 0.0, {}, {}};
    const glm::dvec3 c = glm::cross(em.p[1] - em.p[0], em.p[2] - em.p[0]);
    if (!(glm::length(c) > 0.0)) continue;
    em.n = glm::normalize(c);
    double edge = 0.0;
    for (int k = 0; k < 3; ++k) edge = std::max(edge, glm::length(em.p[(k + 1) % 3] - em.p[k]));
    em.reach = kGapCut * edge;
    em.lo = glm::min(em.p[0], glm::min(em.p[1], em.p[2])) - glm::dvec3(em.reach);
    em.hi = glm::max(em.p[0], glm::max(em.p[1], em.p[2])) + glm::dvec3(em.reach);
    emitters.push_back(em);
  }
  if (emitters.empty()) return;
  // Pairs looked at are bounded: a scene of very many emitters and faces is left uncut.
  if (static_cast<double>(emitters.size()) * static_cast<double>(scene.triangles.size()) > kMaxGapCutPairs) return;

  std::vector<Triangle> out;
  out.reserve(scene.triangles.size());
  std::vector<Poly> pending, pieces;
  std::vector<uint8_t> pending_over, over;
  std::vector<Triangle> cut;
  Poly inside, part_in, part_out;
  for (const Triangle& t : scene.triangles) {
    const glm::dvec3 a(t.p[0]), b(t.p[1]), c(t.p[2]);
    const glm::dvec3 cr = glm::cross(b - a, c - a);
    if (emits(scene.materials[t.material]) || !(glm::length(cr) > 0.0)) {
      out.push_back(t);
      continue;
    }
    const glm::dvec3 n = glm::normalize(cr);
    const glm::dvec3 lo = glm::min(a, glm::min(b, c)), hi = glm::max(a, glm::max(b, c));
    const double tiny = 1e-9 * glm::length(cr);
    pieces.assign(1, Poly{a, b, c});
    over.assign(1, t.in_gap ? 1 : 0);  // whether each piece lies over an emitter's outline
    for (const Emitter& em : emitters) {
      if (pieces.size() > kMaxPiecesPerFace) break;  // many emitters over one face: cut no further
      if (glm::any(glm::lessThan(hi, em.lo)) || glm::any(glm::greaterThan(lo, em.hi))) continue;
      if (!(glm::dot(n, em.n) < -0.9999)) continue;  // facing the emitter, parallel
      const double gap = glm::dot(a - em.p[0], em.n);
      if (!(gap > 0.0 && gap <= em.reach)) continue;
      // The emitter's outline on this face's plane (moved along its normal), and its edges'
      // inward planes (through the edge, containing the normal).
      std::swap(pending, pieces);
      std::swap(pending_over, over);
      pieces.clear();
      over.clear();
      for (std::size_t p = 0; p < pending.size(); ++p) {
        const Poly& piece = pending[p];
        inside = piece;
        std::vector<Poly> outside;
        for (int k = 0; k < 3 && !inside.empty(); ++k) {
          const glm::dvec3 q0 = em.p[k] + em.n * gap, q1 = em.p[(k + 1) % 3] + em.n * gap;
          const glm::dvec3 m = glm::cross(em.n, q1 - q0);  // points into the emitter's outline
          split(inside, q0, m, part_in, part_out);
          const double ai = part_in.size() >= 3 ? area_of(part_in) : 0.0, ao = part_out.size() >= 3 ? area_of(part_out) : 0.0;
          if (ao <= tiny) continue;  // wholly inside this edge
          if (ai <= tiny) {          // wholly outside: not under the emitter
            inside.clear();
            break;
          }
          outside.push_back(part_out);
          inside = part_in;
        }
        if (inside.empty() || outside.empty()) {  // not under the emitter, or wholly under it
          pieces.push_back(piece);
          over.push_back(inside.empty() ? pending_over[p] : 1);
          continue;
        }
        pieces.push_back(inside);
        over.push_back(1);
        for (Poly& o : outside) {
          pieces.push_back(std::move(o));
          over.push_back(pending_over[p]);
        }
      }
    }
    if (pieces.size() == 1) {
      Triangle u = t;
      u.in_gap = over[0] != 0;
      out.push_back(u);
      continue;
    }
    cut.clear();
    bool whole = false;  // a piece that rounding left not quite convex: the face stays uncut
    for (std::size_t p = 0; p < pieces.size(); ++p) {
      const Poly& piece = pieces[p];
      std::vector<glm::vec3> corners(piece.begin(), piece.end());
      std::vector<std::array<uint32_t, 3>> tris;
      try {
        tris = triangulate_polygon(corners);
      } catch (const Error&) {
        whole = true;
        break;
      }
      for (const auto& k : tris) {
        Triangle u = t;
        u.p = {corners[k[0]], corners[k[1]], corners[k[2]]};
        u.in_gap = over[p] != 0;
        const glm::dvec3 uc = glm::cross(glm::dvec3(u.p[1] - u.p[0]), glm::dvec3(u.p[2] - u.p[0]));
        if (!(glm::length(uc) > tiny) || !(glm::dot(uc, n) > 0.0)) continue;  // a sliver of rounding
        cut.push_back(u);
      }
    }
    if (whole) {
      out.push_back(t);
    } else {
      out.insert(out.end(), cut.begin(), cut.end());
    }
    if (out.size() > import::kMaxTriangles) fail("{}: more than {} triangles once cut along emitters", scene.name, import::kMaxTriangles);
  }
  scene.triangles = std::move(out);
}

}  // namespace sirad
