// sirad: the plain C++ reference of a first-shot view: for every pixel sample a ray from the
// eye, tested against every patch in double precision (Moller-Trumbore). It shares nothing
// with the kernels but the shot's parameters (eye, axes, lattice), so it checks the
// clipping, projection, coverage and depth test of kernels/shot.cl independently.
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "engine/shot.h"

namespace sirad {

namespace {

struct Ray {
  glm::dvec3 origin, dir;  // dir = x a + y b + c: its component along c is 1
};

Ray pixel_ray(const SiradShot& s, int face, double x, double y) {
  auto axis = [&](int m) {
    return glm::dvec3(s.axes[9 * face + 3 * m], s.axes[9 * face + 3 * m + 1], s.axes[9 * face + 3 * m + 2]);
  };
  double fx = (x - static_cast<double>(s.offset_x)) / s.scale, fy = (y - static_cast<double>(s.offset_y)) / s.scale;
  return {glm::dvec3(s.eye[0], s.eye[1], s.eye[2]), fx * axis(0) + fy * axis(1) + axis(2)};
}

// Ray parameter of the hit with triangle (a, b, c) (infinity if the ray misses it).
double hit(const Ray& r, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  glm::dvec3 e1 = b - a, e2 = c - a, p = glm::cross(r.dir, e2);
  double det = glm::dot(e1, p);
  if (det == 0.0) return std::numeric_limits<double>::infinity();
  glm::dvec3 s = r.origin - a;
  double u = glm::dot(s, p) / det;
  glm::dvec3 q = glm::cross(s, e1);
  double v = glm::dot(r.dir, q) / det;
  if (u < 0.0 || v < 0.0 || u + v > 1.0) return std::numeric_limits<double>::infinity();
  return glm::dot(e2, q) / det;
}

// What a ray sees: the nearest patch at or beyond the near plane (the kernel's depth test on
// 1 / z, z = the ray parameter since the ray's c component is 1; on a depth tie a face towards
// the eye wins over one facing away, and the later patch over an earlier one facing the same
// way), and how close the runner-up came (relative difference of 1 / z).
struct Seen {
  uint32_t patch = SIRAD_NO_PATCH;
  bool faces = false;
  double runner_up = std::numeric_limits<double>::infinity();
};

Seen trace(const PatchMesh& mesh, const std::vector<glm::vec4>& vertices, const SiradShot& s, const Ray& r) {
  Seen seen;
  double best = std::numeric_limits<double>::infinity();
  double w1 = 0.0, w2 = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const auto& t = mesh.patches[j];
    glm::dvec3 a(vertices[t[0]]), b(vertices[t[1]]), c(vertices[t[2]]);
    double d = hit(r, a, b, c);
    if (!std::isfinite(d) || d < static_cast<double>(s.near_z)) continue;
    bool faces = glm::dot(glm::cross(b - a, c - a), r.dir) < 0.0;
    double w = 1.0 / d, wo = 1.0 / best;
    bool take;
    if (seen.patch == SIRAD_NO_PATCH) take = true;
    else if (std::abs(w - wo) <= static_cast<double>(s.depth_tie) * std::max(w, wo)) take = faces || !seen.faces;
    else take = w > wo;
    // The two nearest hits of all (largest 1 / z), whatever the tie rule picks.
    if (w > w1) {
      w2 = w1;
      w1 = w;
    } else if (w > w2) {
      w2 = w;
    }
    if (take) {
      best = d;
      seen.patch = static_cast<uint32_t>(j);
      seen.faces = faces;
    }
  }
  if (w2 > 0.0) seen.runner_up = (w1 - w2) / w1;
  return seen;
}

uint32_t image_value(const Seen& seen) { return seen.faces ? seen.patch : SIRAD_NO_PATCH; }

template <class Visit>
void for_each_sample(const SiradShot& s, Visit visit) {
  const int H = s.resolution;
  for (int f = 0; f < 5; ++f)
    for (int y = f == 0 ? 0 : H / 2; y < H; ++y)
      for (int x = 0; x < H; ++x) visit(shot_pixel(H, f, y, x), f, x, y);
}

class ReferenceShotEngine final : public ShotEngine {
 public:
  explicit ReferenceShotEngine(const PatchMesh& mesh) : mesh_(mesh), vertices_(centred_vertices(mesh)) {}
  std::string description() const override { return "C++ reference shot (single-threaded)"; }

  void render(const SiradShot& s, std::vector<uint32_t>& image) override {
    image.assign(shot_pixels(s.resolution), SIRAD_NO_PATCH);
    for_each_sample(s, [&](std::size_t i, int f, int x, int y) {
      image[i] = image_value(trace(mesh_, vertices_, s, pixel_ray(s, f, x, y)));
    });
  }

 private:
  const PatchMesh& mesh_;
  std::vector<glm::vec4> vertices_;
};

}  // namespace

std::unique_ptr<ShotEngine> make_reference_shot_engine(const PatchMesh& mesh) {
  return std::make_unique<ReferenceShotEngine>(mesh);
}

void reference_shot_ambiguity(const PatchMesh& mesh, const SiradShot& s, double edge_eps,
                              std::vector<uint8_t>& ambiguous) {
  std::vector<glm::vec4> vertices = centred_vertices(mesh);
  ambiguous.assign(shot_pixels(s.resolution), 0);
  for_each_sample(s, [&](std::size_t i, int f, int x, int y) {
    // An edge within edge_eps: a sample moved that far sees something else. A depth tie:
    // the runner-up within a few ties.
    Seen centre = trace(mesh, vertices, s, pixel_ray(s, f, x, y));
    bool amb = centre.runner_up <= 20.0 * static_cast<double>(s.depth_tie);
    const double dx[4] = {edge_eps, -edge_eps, 0.0, 0.0}, dy[4] = {0.0, 0.0, edge_eps, -edge_eps};
    for (int k = 0; k < 4 && !amb; ++k)
      amb = image_value(trace(mesh, vertices, s, pixel_ray(s, f, x + dx[k], y + dy[k]))) != image_value(centre);
    ambiguous[i] = amb ? 1 : 0;
  });
}

}  // namespace sirad
