// sirad: bundle parameters from (seed, index): Philox draws, the frame, the jittered grid.
#include "engine/bundle.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Random123/philox.h>
#include <glm/geometric.hpp>

#include "util/check.h"
#include "util/error.h"

namespace sirad {

namespace {
// A 32-bit draw mapped to the open interval (0, 1).
double unit_open(uint32_t r) { return (static_cast<double>(r) + 0.5) * 0x1p-32; }
}  // namespace

Directions parse_directions(const std::string& name) {
  if (name == "random") return Directions::random;
  if (name == "stratified") return Directions::stratified;
  fail("unknown directions '{}' (expected random or stratified)", name);
}

const char* to_string(Directions directions) {
  return directions == Directions::random ? "random" : "stratified";
}

// Stratified directions: K = side^2 strata per block, and G sequences interleaved so that
// same-block bundles of one chain are G steps apart, with G the smallest where rho_max^G <=
// 1e-3 (at most 256). That bounds the chain's bias from the dependence inside a block by about
// 0.3 rho_max^G / (K - 1): the derivation, the measurements and why the average rule refuses
// stratification are in docs/DESIGN.md, "Stratified directions and the chain's bias".
Sampling sampling_plan(const PatchMesh& mesh, Directions directions) {
  Sampling s;
  s.directions = directions;
  if (directions == Directions::random) return s;
  float rho_max = 0.0f;
  for (const auto& m : mesh.materials) rho_max = std::max({rho_max, m.reflectance.x, m.reflectance.y, m.reflectance.z});
  double g = 1.0;
  if (rho_max >= 1.0f) g = 256.0;
  else if (rho_max > 0.0f) g = std::ceil(std::log(1e-3) / std::log(static_cast<double>(rho_max)));
  s.interleave = static_cast<uint32_t>(std::clamp(g, 1.0, 256.0));
  s.side = 16;
  return s;
}

namespace {

// Philox counters (key: the run seed): bundle draws use {index, stream, 0}; the tags below
// keep the other draws on counters no bundle draw uses.
constexpr uint32_t kSignTag = 0x20000000u;  // word 2 of a bundle's second draw (its sign)
constexpr uint32_t kOrderTag = 0x40000000u;  // word 2 of a block's order draws

r123::Philox4x32::ctr_type philox_draw(uint64_t seed, uint32_t w0, uint32_t w1, uint32_t w2, uint32_t w3) {
  r123::Philox4x32 philox;
  r123::Philox4x32::ctr_type ctr = {{w0, w1, w2, w3}};
  r123::Philox4x32::key_type key = {{static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32)}};
  return philox(ctr, key);
}

void check_sampling(const Sampling& s) {
  if (s.interleave < 1 || s.interleave > 256 || s.side < 1 || s.side > 64)
    fail("stratified sampling: interleave {} (1..256) or side {} (1..64) out of range", s.interleave, s.side);
}

// Concentric map of [0, 1)^2 onto the unit disk (Shirley & Chiu 1997; area-preserving up to
// the factor pi / 4), then the Lambert lift onto the upper hemisphere: z = 1 - r^2 (uniform
// when r^2 is), (x, y) scaled by sqrt(2 - r^2). Equal-area strata stay compact.
glm::dvec3 square_to_hemisphere(double u, double v) {
  double a = 2.0 * u - 1.0, b = 2.0 * v - 1.0;
  double r, phi;
  if (a == 0.0 && b == 0.0) return {0.0, 0.0, 1.0};
  if (a * a > b * b) {
    r = a;
    phi = (std::numbers::pi / 4.0) * (b / a);
  } else {
    r = b;
    phi = std::numbers::pi / 2.0 - (std::numbers::pi / 4.0) * (a / b);
  }
  double x = r * std::cos(phi), y = r * std::sin(phi), r2 = r * r;
  double scale = std::sqrt(std::max(0.0, 2.0 - r2));
  return {x * scale, y * scale, 1.0 - r2};
}

}  // namespace

std::vector<uint32_t> block_orders(uint64_t seed, uint64_t block, uint32_t tag, uint32_t k, uint32_t orders) {
  // Uniform random permutations of 0..k-1 (Fisher-Yates; j = floor(r (i + 1) / 2^32) is
  // uniform on 0..i up to (i + 1) / 2^32 < 1e-6), from Philox draws on {block, tag, 1 + c}.
  const uint32_t n = k * orders;
  std::vector<uint32_t> order(n), r(n);
  for (uint32_t c = 0; 4 * c < n; ++c) {
    auto d = philox_draw(seed, static_cast<uint32_t>(block), static_cast<uint32_t>(block >> 32), tag, 1u + c);
    for (uint32_t q = 0; q < 4 && 4 * c + q < n; ++q) r[4 * c + q] = d[q];
  }
  for (uint32_t p = 0; p < orders; ++p) {
    uint32_t* o = order.data() + p * k;
    for (uint32_t i = 0; i < k; ++i) o[i] = i;
    for (uint32_t i = k - 1; i > 0; --i) {
      uint32_t j = static_cast<uint32_t>((static_cast<uint64_t>(r[p * k + i]) * (i + 1)) >> 32);
      std::swap(o[i], o[j]);
    }
  }
  return order;
}

StratumOf stratum_of(uint64_t seed, uint64_t index, Stream stream, const Sampling& sampling) {
  StratumOf out;
  if (sampling.directions == Directions::random || stream != Stream::bundles) return out;
  check_sampling(sampling);
  const uint32_t g = sampling.interleave, k = sampling.side * sampling.side;
  out.sequence = index % g;
  uint64_t t = index / g;
  out.block = t / k;
  const uint32_t position = static_cast<uint32_t>(t % k);
  // Two uniform random permutations of the K strata, keyed by (seed, stream, sequence, block).
  const uint32_t w2 = kOrderTag | (static_cast<uint32_t>(stream) << 16) | static_cast<uint32_t>(out.sequence);
  std::vector<uint32_t> order = block_orders(seed, out.block, w2, k, 2);
  out.direction = order[position];
  out.jitter = order[k + position];
  return out;
}

BundleDraw draw_bundle(uint64_t seed, uint64_t index, Stream stream, const Sampling& sampling) {
  auto r = philox_draw(seed, static_cast<uint32_t>(index), static_cast<uint32_t>(index >> 32),
                       static_cast<uint32_t>(stream), 0u);
  if (sampling.directions == Directions::random || stream != Stream::bundles) {
    // Uniform on the sphere: z uniform in (-1, 1), azimuth uniform (Archimedes).
    double z = 1.0 - 2.0 * unit_open(r[0]);
    double phi = 2.0 * std::numbers::pi * unit_open(r[1]);
    double s = std::sqrt(std::max(0.0, 1.0 - z * z));
    return {glm::dvec3(s * std::cos(phi), s * std::sin(phi), z), unit_open(r[2]), unit_open(r[3])};
  }
  // Stratified: uniform inside the bundle's direction stratum (a cell of the n x n grid on the
  // square, mapped onto the hemisphere) and jitter stratum (a cell of the n x n grid on the
  // lattice cell), with a random sign: uniform on the sphere and in the cell marginally.
  StratumOf st = stratum_of(seed, index, stream, sampling);
  const double n = sampling.side;
  const uint32_t side = sampling.side;
  glm::dvec3 w = square_to_hemisphere((st.direction % side + unit_open(r[0])) / n,
                                      (st.direction / side + unit_open(r[1])) / n);
  auto sign = philox_draw(seed, static_cast<uint32_t>(index), static_cast<uint32_t>(index >> 32),
                          kSignTag | static_cast<uint32_t>(stream), 0u);
  if (sign[0] & 1u) w = -w;
  w /= glm::length(w);
  return {w, (st.jitter % side + unit_open(r[2])) / n, (st.jitter / side + unit_open(r[3])) / n};
}

double cell_area(const PatchMesh& mesh, int grid) {
  double h = 2.0 * static_cast<double>(mesh.bound_radius) / (grid - 1);
  return h * h;
}

SiradBundle make_bundle(const PatchMesh& mesh, int grid, uint64_t seed, uint64_t index,
                        Stream stream, const Sampling& sampling) {
  if (grid < 2) fail("grid must be at least 2 lines per side (got {})", grid);
  BundleDraw d = draw_bundle(seed, index, stream, sampling);
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

namespace {

// sum over patches of per_patch(area, perimeter) in cells of the grid, with a 1 % margin.
template <class PerPatch>
uint64_t bound_over_patches(const PatchMesh& mesh, int grid, PerPatch per_patch) {
  double h = std::sqrt(cell_area(mesh, grid));
  double total = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const auto& t = mesh.patches[j];
    glm::vec3 a = mesh.vertices[t[0]], b = mesh.vertices[t[1]], c = mesh.vertices[t[2]];
    double perimeter = glm::length(glm::dvec3(b - a)) + glm::length(glm::dvec3(c - b)) +
                       glm::length(glm::dvec3(a - c));
    total += per_patch(mesh.area[j] / (h * h), perimeter / h);
  }
  return static_cast<uint64_t>(std::ceil(total * 1.01)) + 16;
}

}  // namespace

uint64_t capacity_bound(const PatchMesh& mesh, int grid) {
  return bound_over_patches(mesh, grid, [](double area, double perimeter) { return area + perimeter / 2.0 + 1.0; });
}

uint64_t span_bound(const PatchMesh& mesh, int grid) {
  return bound_over_patches(mesh, grid, [](double, double perimeter) { return perimeter / 2.0 + 2.0; });
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

void BundleEngine::run_batch(std::span<const SiradBundle> bundles, std::span<const glm::vec4> radiance,
                             std::span<BundleResult> results) {
  SIRAD_CHECK(results.size() == bundles.size(), "run_batch: {} results for {} bundles", results.size(), bundles.size());
  for (std::size_t k = 0; k < bundles.size(); ++k) run(bundles[k], radiance, results[k]);
}

}  // namespace sirad
