// sirad: the segments along which faces meet (contacts.h).
#include "scene/contacts.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <utility>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

namespace sirad {

namespace {

// Faces closer to parallel than this (|cos| of the angle between normals) meet no face: 25 deg.
constexpr double kMaxParallel = 0.906;

struct Box {
  glm::dvec3 lo, hi;
};

// Whether two triangles have the same corners (in any order): a face and its twin.
bool same_corners(const std::array<glm::dvec3, 3>& a, const std::array<glm::dvec3, 3>& b) {
  for (const glm::dvec3& x : a)
    if (x != b[0] && x != b[1] && x != b[2]) return false;
  return true;
}

}  // namespace

double contact_tolerance(const Scene& scene) {
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const Triangle& t : scene.triangles)
    for (const glm::vec3& p : t.p) lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
  return 1e-5 * 0.5 * glm::length(hi - lo);
}

bool clip_to_triangle(const std::array<glm::dvec3, 3>& t, const glm::dvec3& n, glm::dvec3& p, glm::dvec3& q) {
  double t0 = 0.0, t1 = 1.0;
  for (int k = 0; k < 3; ++k) {
    const glm::dvec3 m = glm::cross(n, t[(k + 1) % 3] - t[k]);  // inward for a counter-clockwise triangle
    const double sp = glm::dot(p - t[k], m), sq = glm::dot(q - t[k], m);
    if (sp < 0.0 && sq < 0.0) return false;
    if (sp < 0.0) t0 = std::max(t0, sp / (sp - sq));
    if (sq < 0.0) t1 = std::min(t1, sp / (sp - sq));
  }
  if (!(t1 > t0)) return false;
  const glm::dvec3 d = q - p;
  q = p + d * t1;
  p = p + d * t0;
  return true;
}

std::vector<std::vector<ContactSegment>> contact_segments(const Scene& scene, double tolerance) {
  const std::vector<Triangle>& tris = scene.triangles;
  const std::size_t count = tris.size();
  std::vector<std::vector<ContactSegment>> out(count);
  std::vector<Box> box(count);
  std::vector<glm::dvec3> normal(count);
  std::vector<uint8_t> usable(count, 0);
  for (std::size_t i = 0; i < count; ++i) {
    const glm::dvec3 a(tris[i].p[0]), b(tris[i].p[1]), c(tris[i].p[2]);
    box[i] = {glm::min(a, glm::min(b, c)) - tolerance, glm::max(a, glm::max(b, c)) + tolerance};
    const glm::dvec3 cr = glm::cross(b - a, c - a);
    const double length = glm::length(cr);
    if (length > 0.0 && std::isfinite(length)) {
      normal[i] = cr / length;
      usable[i] = 1;
    }
  }
  // Face g meets face f's plane in front of it: the segment where it does, within f.
  const auto meet = [&](std::size_t f, std::size_t g) {
    std::vector<ContactSegment>& mine = out[f];
    if (!usable[f] || !usable[g] || mine.size() >= kMaxContactsPerFace || tris[f].unlit || scene.materials[tris[f].material].emits()) return;
    const glm::dvec3& n = normal[f];
    if (std::abs(glm::dot(n, normal[g])) > kMaxParallel) return;
    const glm::dvec3 o(tris[f].p[0]);
    std::array<glm::dvec3, 3> gp;
    std::array<double, 3> d;
    for (int k = 0; k < 3; ++k) {
      gp[k] = glm::dvec3(tris[g].p[k]);
      d[k] = glm::dot(gp[k] - o, n);
    }
    if (!(*std::max_element(d.begin(), d.end()) > tolerance) || !(*std::min_element(d.begin(), d.end()) <= tolerance)) return;
    glm::dvec3 at[4];
    int points = 0;
    for (int k = 0; k < 3; ++k)
      if (std::abs(d[k]) <= tolerance) at[points++] = gp[k] - n * d[k];
    for (int k = 0; k < 3; ++k) {
      const int l = (k + 1) % 3;
      if ((d[k] < -tolerance && d[l] > tolerance) || (d[k] > tolerance && d[l] < -tolerance))
        at[points++] = gp[k] + (gp[l] - gp[k]) * (d[k] / (d[k] - d[l]));
    }
    if (points != 2) return;  // g touches the plane at a point only
    glm::dvec3 p = at[0], q = at[1];
    const std::array<glm::dvec3, 3> ft = {o, glm::dvec3(tris[f].p[1]), glm::dvec3(tris[f].p[2])};
    if (!(glm::length(q - p) > tolerance) || !clip_to_triangle(ft, n, p, q) || !(glm::length(q - p) > tolerance)) return;
    const glm::dvec3 facing = glm::normalize(normal[g] - n * glm::dot(normal[g], n));
    for (const ContactSegment& s : mine)
      if (((glm::length(s.p - p) <= tolerance && glm::length(s.q - q) <= tolerance) ||
           (glm::length(s.p - q) <= tolerance && glm::length(s.q - p) <= tolerance)) &&
          glm::dot(s.facing, facing) > 0.0)
        return;  // one face cut in two along it (a twin's faces the other way, and counts)
    mine.push_back({p, q, facing});
  };
  // Sweep and prune along x, in a fixed order (the same in every process).
  std::vector<uint32_t> order(count);
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return box[a].lo.x < box[b].lo.x || (box[a].lo.x == box[b].lo.x && a < b); });
  double pairs = 0.0;
  for (std::size_t ia = 0; ia < count; ++ia) {
    const uint32_t a = order[ia];
    for (std::size_t ib = ia + 1; ib < count && box[order[ib]].lo.x <= box[a].hi.x; ++ib) {
      const uint32_t b = order[ib];
      if (++pairs > kMaxContactPairs) return out;
      if (glm::any(glm::lessThan(box[a].hi, box[b].lo)) || glm::any(glm::lessThan(box[b].hi, box[a].lo))) continue;
      meet(a, b);
      meet(b, a);
    }
  }
  return out;
}

bool CoverTest::inside(uint32_t face, const std::vector<ContactSegment>& contacts, const glm::dvec3& point) {
  if (tests_ > kMaxCoverTests) return false;
  // Behind the face that stands nearest: the segment nearest the point among those it lies
  // beside (its foot along the segment), and no face at that distance facing the point.
  double nearest_line = std::numeric_limits<double>::infinity();
  bool behind = false, before = false;
  for (const ContactSegment& c : contacts) {
    const glm::dvec3 d = c.q - c.p;
    const double along = glm::dot(point - c.p, d) / glm::dot(d, d);
    if (along < 0.0 || along > 1.0) continue;
    const double side = glm::dot(point - c.p, c.facing);
    const double distance = glm::length(point - c.p - d * along);
    if (distance < nearest_line - tolerance_) behind = before = false;
    if (distance > nearest_line + tolerance_) continue;
    nearest_line = std::min(nearest_line, distance);
    (side < 0.0 ? behind : before) = true;
  }
  if (!behind || before) return false;
  if (face != face_) {
    // The candidates: triangles with a corner in front of the face, overlapping it across its normal.
    face_ = face;
    candidates_.clear();
    const Triangle& f = scene_.triangles[face];
    const glm::dvec3 a(f.p[0]), b(f.p[1]), c(f.p[2]);
    normal_ = glm::normalize(glm::cross(b - a, c - a));
    u_ = glm::normalize(b - a);
    v_ = glm::cross(normal_, u_);
    const auto across = [&](const glm::dvec3& x) { return glm::dvec2(glm::dot(x - a, u_), glm::dot(x - a, v_)); };
    const glm::dvec2 fa = across(a), fb = across(b), fc = across(c);
    const glm::dvec2 lo = glm::min(fa, glm::min(fb, fc)) - tolerance_, hi = glm::max(fa, glm::max(fb, fc)) + tolerance_;
    tests_ += static_cast<double>(scene_.triangles.size());
    for (const Triangle& t : scene_.triangles) {
      const std::array<glm::dvec3, 3> p = {glm::dvec3(t.p[0]), glm::dvec3(t.p[1]), glm::dvec3(t.p[2])};
      if (!(std::max({glm::dot(p[0] - a, normal_), glm::dot(p[1] - a, normal_), glm::dot(p[2] - a, normal_)}) > tolerance_)) continue;
      const glm::dvec2 pa = across(p[0]), pb = across(p[1]), pc = across(p[2]);
      const glm::dvec2 tlo = glm::min(pa, glm::min(pb, pc)), thi = glm::max(pa, glm::max(pb, pc));
      if (thi.x < lo.x || thi.y < lo.y || tlo.x > hi.x || tlo.y > hi.y) continue;
      candidates_.push_back({p, tlo.x, thi.x, tlo.y, thi.y});
    }
  }
  // The faces along the ray (Moller-Trumbore, edges included), fronts and backs.
  const glm::dvec3 o = point + normal_ * (2.0 * tolerance_);
  const glm::dvec3 at = o - glm::dvec3(scene_.triangles[face].p[0]);
  const double ou = glm::dot(at, u_), ov = glm::dot(at, v_);
  hits_.clear();
  for (const Candidate& k : candidates_) {
    if (ou < k.lo_u || ou > k.hi_u || ov < k.lo_v || ov > k.hi_v) continue;
    tests_ += 1.0;
    const glm::dvec3 e1 = k.p[1] - k.p[0], e2 = k.p[2] - k.p[0];
    const glm::dvec3 pv = glm::cross(normal_, e2);
    const double det = glm::dot(e1, pv);
    if (det == 0.0) continue;  // parallel to the ray
    const glm::dvec3 tv = o - k.p[0];
    const double bu = glm::dot(tv, pv) / det;
    if (bu < 0.0 || bu > 1.0) continue;
    const glm::dvec3 qv = glm::cross(tv, e1);
    const double bv = glm::dot(normal_, qv) / det;
    if (bv < 0.0 || bu + bv > 1.0) continue;
    const double t = glm::dot(e2, qv) / det;
    if (t > 0.0) hits_.push_back({t, glm::dot(glm::cross(e1, e2), normal_) > 0.0, &k});  // a back looks along the ray
  }
  // The first place it meets decides: a back there (with no twin at its place) is the inside
  // of a solid, whatever touches it (a wall's top under a ceiling: the ceiling's front); fronts
  // only are open. A face and its twin (the same corners, reversed: a two-sided surface) are
  // passed through.
  std::sort(hits_.begin(), hits_.end(), [](const Hit& a, const Hit& b) { return a.t < b.t; });
  for (std::size_t i = 0; i < hits_.size();) {
    const std::size_t first = i;
    for (const double t = hits_[i].t; i < hits_.size() && hits_[i].t <= t + tolerance_; ++i) {}
    if (i - first > kMaxFacesAtOnePlace) return false;
    bool front = false, back = false;
    for (std::size_t h = first; h < i; ++h) {
      bool twin = false;
      for (std::size_t o = first; o < i && !twin; ++o)
        twin = hits_[o].back != hits_[h].back && same_corners(hits_[o].face->p, hits_[h].face->p);
      if (!twin) (hits_[h].back ? back : front) = true;
    }
    if (back) return true;
    if (front) return false;
  }
  return false;
}

}  // namespace sirad

