// sirad: bundle parameters from (seed, index): Philox draws, the frame, the jittered grid.
#include "core/bundle.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Random123/philox.h>
#include <glm/geometric.hpp>

#include "core/error.h"

namespace sirad {

namespace {
// A 32-bit draw mapped to the open interval (0, 1).
double unit_open(uint32_t r) { return (static_cast<double>(r) + 0.5) * 0x1p-32; }
}  // namespace

BundleDraw draw_bundle(uint64_t seed, uint64_t index, Stream stream) {
  r123::Philox4x32 philox;
  r123::Philox4x32::ctr_type ctr = {{static_cast<uint32_t>(index),
                                     static_cast<uint32_t>(index >> 32),
                                     static_cast<uint32_t>(stream), 0u}};
  r123::Philox4x32::key_type key = {{static_cast<uint32_t>(seed),
                                     static_cast<uint32_t>(seed >> 32)}};
  auto r = philox(ctr, key);
  // Uniform on the sphere: z uniform in (-1, 1), azimuth uniform (Archimedes).
  double z = 1.0 - 2.0 * unit_open(r[0]);
  double phi = 2.0 * std::numbers::pi * unit_open(r[1]);
  double s = std::sqrt(std::max(0.0, 1.0 - z * z));
  return {glm::dvec3(s * std::cos(phi), s * std::sin(phi), z), unit_open(r[2]), unit_open(r[3])};
}

double cell_area(const PatchMesh& mesh, int grid) {
  double h = 2.0 * static_cast<double>(mesh.bound_radius) / (grid - 1);
  return h * h;
}

SiradBundle make_bundle(const PatchMesh& mesh, int grid, uint64_t seed, uint64_t index,
                        Stream stream) {
  if (grid < 2) fail("grid must be at least 2 lines per side (got {})", grid);
  BundleDraw d = draw_bundle(seed, index, stream);
  const glm::dvec3 w = d.direction;
  // Right-handed orthonormal frame (u, v, w), u x v = w (Duff et al. 2017).
  double sign = std::copysign(1.0, w.z);
  double a = -1.0 / (sign + w.z);
  double bb = w.x * w.y * a;
  glm::dvec3 u(1.0 + sign * w.x * w.x * a, sign * bb, -sign * w.x);
  glm::dvec3 v(bb, sign + w.y * w.y * a, -w.y);

  SiradBundle b{};
  for (int k = 0; k < 3; ++k) {
    b.u[k] = static_cast<float>(u[k]);
    b.v[k] = static_cast<float>(v[k]);
    b.w[k] = static_cast<float>(w[k]);
  }
  // Lines at integer grid points 0..R-1 with spacing h = 2r/(R-1), shifted by the jitter:
  // X = (q.u)/h + (R-1)/2 - jitter maps the bounding disk [-r, r] into [-jitter, R-1-jitter],
  // so every lattice line that can meet the scene is one of the R.
  double scale = (grid - 1) / (2.0 * static_cast<double>(mesh.bound_radius));
  b.scale = static_cast<float>(scale);
  b.offset_x = static_cast<float>((grid - 1) / 2.0 - d.jitter_x);
  b.offset_y = static_cast<float>((grid - 1) / 2.0 - d.jitter_y);
  b.grid = grid;
  b.rows_per_band = grid;
  b.bands = 1;
  b.capacity = 0;  // scratch sizes are the engine's
  b.partial_capacity = 0;
  b.background[0] = mesh.background.x;
  b.background[1] = mesh.background.y;
  b.background[2] = mesh.background.z;
  b.background[3] = 0.0f;
  // Two faces closer than 1e-5 of the scene's radius along a line are one place (a two-sided
  // wall made of two coincident one-sided faces): far above the rounding of depths computed
  // from different vertices, far below any gap a scene means light to pass through.
  b.depth_tie = static_cast<float>(1e-5 * static_cast<double>(mesh.bound_radius));
  return b;
}

uint64_t capacity_bound(const PatchMesh& mesh, int grid) {
  double h = std::sqrt(cell_area(mesh, grid));
  double total = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const auto& t = mesh.patches[j];
    glm::vec3 a = mesh.vertices[t[0]], b = mesh.vertices[t[1]], c = mesh.vertices[t[2]];
    double perimeter = glm::length(glm::dvec3(b - a)) + glm::length(glm::dvec3(c - b)) +
                       glm::length(glm::dvec3(a - c));
    total += mesh.area[j] / (h * h) + perimeter / (2.0 * h) + 1.0;
  }
  return static_cast<uint64_t>(std::ceil(total * 1.01)) + 16;
}

int auto_grid(const PatchMesh& mesh) {
  if (mesh.size() == 0) return 32;
  std::vector<float> areas = mesh.area;
  auto mid = areas.begin() + areas.size() / 2;
  std::nth_element(areas.begin(), mid, areas.end());
  // Expected crossings of a patch of area A per bundle: A / (2 delta). Aim for 4.
  double h = std::sqrt(static_cast<double>(*mid) / 8.0);
  double r = 2.0 * static_cast<double>(mesh.bound_radius) / h + 1.0;
  return static_cast<int>(std::clamp(std::ceil(r), 32.0, 2048.0));
}

std::vector<glm::vec4> centred_vertices(const PatchMesh& mesh) {
  std::vector<glm::vec4> out(mesh.vertices.size());
  glm::dvec3 c(mesh.bound_center);
  for (std::size_t i = 0; i < out.size(); ++i) {
    glm::dvec3 q = glm::dvec3(mesh.vertices[i]) - c;
    out[i] = glm::vec4(static_cast<float>(q.x), static_cast<float>(q.y), static_cast<float>(q.z), 0.0f);
  }
  return out;
}

}  // namespace sirad
