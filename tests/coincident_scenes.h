// sirad tests: scenes with coincident and touching faces (tests/engine/coincident_test.cpp has what
// each is for), built as OBJ text so that every variant (gap, angle, strips) is one call.
#pragma once
#include <cmath>
#include <numbers>
#include <string>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

#include "scene/scene.h"

namespace sirad::test {

using glm::dvec3;

// OBJ text built from quads and triangles, every point moved by one rotation about the origin.
class ObjBuilder {
 public:
  explicit ObjBuilder(glm::dmat3 rotation = glm::dmat3(1.0)) : rotation_(rotation) {}
  void material(const std::string& name) { obj_ += "usemtl " + name + "\n"; }
  // Counter-clockwise seen from the front; split along the diagonal p0-p2 (`other`: p1-p3).
  void quad(dvec3 p0, dvec3 p1, dvec3 p2, dvec3 p3, bool other = false) {
    if (other) {
      triangle(p0, p1, p3);
      triangle(p1, p2, p3);
    } else {
      triangle(p0, p1, p2);
      triangle(p0, p2, p3);
    }
  }
  void triangle(dvec3 a, dvec3 b, dvec3 c) {
    for (dvec3 p : {a, b, c}) {
      dvec3 q = rotation_ * p;
      obj_ += fmt::format("v {:.9g} {:.9g} {:.9g}\n", q.x, q.y, q.z);
    }
    obj_ += fmt::format("f {} {} {}\n", vertices_ + 1, vertices_ + 2, vertices_ + 3);
    vertices_ += 3;
  }
  // A rectangle in the plane x = X from (y0, z0) to (y1, z1), facing +x or -x, cut into
  // `strips` along z (their corners fall on the middle of a neighbour's edges: T-junctions).
  void wall_x(double X, double y0, double y1, double z0, double z1, bool towards_plus, bool other = false,
              int strips = 1) {
    for (int s = 0; s < strips; ++s) {
      double za = z0 + (z1 - z0) * s / strips, zb = z0 + (z1 - z0) * (s + 1) / strips;
      if (towards_plus) quad({X, y0, za}, {X, y1, za}, {X, y1, zb}, {X, y0, zb}, other);
      else quad({X, y0, za}, {X, y0, zb}, {X, y1, zb}, {X, y1, za}, other);
    }
  }
  Scene scene(const std::string& name, const std::string& mtl) const {
    return parse_obj(name, "mtllib s.mtl\n" + obj_, {{"s.mtl", mtl}});
  }
  const glm::dmat3& rotation() const { return rotation_; }

 private:
  glm::dmat3 rotation_;
  std::string obj_;
  int vertices_ = 0;
};

// A rotation by `deg` about the axis (1, 2, 3): no coordinate of a rotated wall is exact.
inline glm::dmat3 oblique(double deg) {
  dvec3 k = glm::normalize(dvec3(1.0, 2.0, 3.0));
  double t = deg * std::numbers::pi / 180.0, c = std::cos(t), s = std::sin(t);
  glm::dmat3 K(0.0, k.z, -k.y, -k.z, 0.0, k.x, k.y, -k.x, 0.0);  // column-major cross matrix
  return glm::dmat3(1.0) + s * K + (1.0 - c) * K * K;
}

inline const char* kMtl =
    "newmtl wall\nKd 0.7 0.7 0.7\nnewmtl panel\nKd 0.7 0.7 0.7\nnewmtl floor\nKd 0.5 0.45 0.4\nnewmtl rug\nKd 0.8 0.25 0.2\n"
    "newmtl lamp\nKd 0.5 0.5 0.5\nKe 10 10 10\nnewmtl big_lamp\nKd 0.5 0.5 0.5\nKe 2 2 2\n";

// Two rooms 4 x 3 x 4 m side by side (x in [0, 4] and [4, 8], y up), one floor and one ceiling
// over both, joined by a doorway (z in [1.5, 2.5], y below 2.2) in a zero-thickness wall at x = 4:
// two faces back to back, cut into different rectangles and split along other diagonals, the
// +x one moved by `gap`. The wall stands on the floor in the middle of its face. A lamp hangs in
// room A only. `strips` cuts the outer walls into strips (T-junctions with the floor's edges).
inline Scene two_rooms(double gap, glm::dmat3 rotation, int strips = 1) {
  ObjBuilder o(rotation);
  const double W = 8, H = 3, D = 4, X = 4, z0 = 1.5, z1 = 2.5, yd = 2.2;
  o.material("floor");
  o.quad({0, 0, 0}, {0, 0, D}, {W, 0, D}, {W, 0, 0});
  o.material("wall");
  o.quad({0, H, 0}, {W, H, 0}, {W, H, D}, {0, H, D});
  o.wall_x(0, 0, H, 0, D, true, false, strips);
  o.wall_x(W, 0, H, 0, D, false, true, strips);
  for (int s = 0; s < strips; ++s) {  // z = 0 (facing +z) and z = D (facing -z), in strips along x
    double xa = W * s / strips, xb = W * (s + 1) / strips;
    o.quad({xa, 0, 0}, {xb, 0, 0}, {xb, H, 0}, {xa, H, 0});
    o.quad({xa, 0, D}, {xa, H, D}, {xb, H, D}, {xb, 0, D}, true);
  }
  // The thin wall: towards room A (-x) as three rectangles around the doorway ...
  o.wall_x(X, 0, H, 0, z0, false);
  o.wall_x(X, 0, H, z1, D, false);
  o.wall_x(X, yd, H, z0, z1, false);
  // ... and towards room B (+x) as three others, split the other way.
  o.wall_x(X + gap, yd, H, 0, D, true, true);
  o.wall_x(X + gap, 0, yd, 0, z0, true, true);
  o.wall_x(X + gap, 0, yd, z1, D, true, true);
  o.material("lamp");
  o.quad({1.5, 2.95, 1.5}, {2.5, 2.95, 1.5}, {2.5, 2.95, 2.5}, {1.5, 2.95, 2.5});
  return o.scene(fmt::format("two-rooms gap {}", gap), kMtl);
}

// The floor (material `floor`), ceiling and walls (`wall`) of a closed room 4 x 3 x 4 m, facing in.
inline void room_shell(ObjBuilder& o) {
  const double W = 4, H = 3, D = 4;
  o.material("floor");
  o.quad({0, 0, 0}, {0, 0, D}, {W, 0, D}, {W, 0, 0});
  o.material("wall");
  o.quad({0, H, 0}, {W, H, 0}, {W, H, D}, {0, H, D});
  o.wall_x(0, 0, H, 0, D, true);
  o.wall_x(W, 0, H, 0, D, false);
  o.quad({0, 0, 0}, {W, 0, 0}, {W, H, 0}, {0, H, 0});
  o.quad({0, 0, D}, {0, H, D}, {W, H, D}, {W, 0, D});
}

// A closed room 4 x 3 x 4 m (room_shell) with a two-sided lamp panel 1.2 x 0.6 m hung `gap` below
// the ceiling (as Blender exports an emitting plane: its upper side emits into the gap too), its
// front facing down.
inline Scene lamp_under_ceiling(double gap) {
  ObjBuilder o;
  room_shell(o);
  o.material("two_sided_lamp");
  const double y = 3.0 - gap;
  o.quad({1.4, y, 1.7}, {1.4, y, 2.3}, {2.6, y, 2.3}, {2.6, y, 1.7});
  return o.scene(fmt::format("lamp {} m under the ceiling", gap),
                 std::string(kMtl) + "newmtl two_sided_lamp\nKd 0.5 0.5 0.5\nKe 5 5 5\nsirad_two_sided 1\n");
}

// A closed room 4 x 3 x 4 m (room_shell) with a box lamp 0.6 x 0.6 x 0.03 m whose lid is `gap`
// below the ceiling, its faces out; `two_sided` as Blender exports an emitting box: its inside
// emits too, a closed cavity the lid hides from the ceiling.
inline Scene box_lamp_under_ceiling(double gap, bool two_sided) {
  ObjBuilder o;
  room_shell(o);
  o.material("box_lamp");
  const double x0 = 1.7, x1 = 2.3, z0 = 1.7, z1 = 2.3, y1 = 3.0 - gap, y0 = y1 - 0.03;
  o.quad({x0, y1, z0}, {x0, y1, z1}, {x1, y1, z1}, {x1, y1, z0});  // lid, up
  o.quad({x0, y0, z0}, {x1, y0, z0}, {x1, y0, z1}, {x0, y0, z1});  // bottom, down
  o.wall_x(x0, y0, y1, z0, z1, false);
  o.wall_x(x1, y0, y1, z0, z1, true);
  o.quad({x0, y0, z0}, {x0, y1, z0}, {x1, y1, z0}, {x1, y0, z0});  // towards -z
  o.quad({x0, y0, z1}, {x1, y0, z1}, {x1, y1, z1}, {x0, y1, z1});  // towards +z
  return o.scene(fmt::format("box lamp {} m under the ceiling", gap),
                 std::string(kMtl) + "newmtl box_lamp\nKd 0.8 0.8 0.8\nKe 8 8 8\n" + (two_sided ? "sirad_two_sided 1\n" : ""));
}

// A closed room 4 x 3 x 4 m with a large ceiling lamp and a free-standing zero-thickness panel
// (2 x 1.6 m of material `panel`, turned 30 degrees about y, its front tilted 50 degrees up towards
// the lamp): its front as a 2 x 2 grid of rectangles, its back as one rectangle split along the
// other diagonal.
inline Scene panel_room(glm::dmat3 rotation) {
  ObjBuilder o(rotation);
  room_shell(o);
  o.material("panel");
  // The panel in its own frame (u across, v up, normal n), centred at (2, 1.3, 2).
  double a = 30 * std::numbers::pi / 180, t = 50 * std::numbers::pi / 180;
  dvec3 n(std::cos(a) * std::cos(t), std::sin(t), std::sin(a) * std::cos(t));
  dvec3 u = glm::normalize(glm::cross(dvec3(0, 1, 0), n)), v = glm::cross(n, u), c(2.0, 1.3, 2.0);
  auto at = [&](double s, double r) { return c + u * s + v * r; };
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)  // front (towards n): u, v, n right-handed, so (s, r) CCW
      o.quad(at(-1 + i, -0.8 + 0.8 * j), at(i, -0.8 + 0.8 * j), at(i, 0.8 * j), at(-1 + i, 0.8 * j));
  o.quad(at(-1, -0.8), at(-1, 0.8), at(1, 0.8), at(1, -0.8), true);  // back (towards -n)
  o.material("big_lamp");
  o.quad({0.8, 2.95, 0.8}, {3.2, 2.95, 0.8}, {3.2, 2.95, 3.2}, {0.8, 2.95, 3.2});
  return o.scene("panel room", kMtl);
}

// A closed room 4 x 3 x 4 m with a large ceiling lamp (2.4 m square, so that the lines finding
// it are many) and a rug (1.6 x 1.2 m, later in the file than the floor) `gap` above the floor,
// both facing up.
inline Scene rug_room(double gap, glm::dmat3 rotation) {
  ObjBuilder o(rotation);
  room_shell(o);
  o.material("big_lamp");
  o.quad({0.8, 2.95, 0.8}, {3.2, 2.95, 0.8}, {3.2, 2.95, 3.2}, {0.8, 2.95, 3.2});
  o.material("rug");
  o.quad({1.1, gap, 1.3}, {1.1, gap, 2.5}, {2.7, gap, 2.5}, {2.7, gap, 1.3}, true);
  return o.scene(fmt::format("rug room gap {}", gap), kMtl);
}

}  // namespace sirad::test
