// sirad: the first shot's draws, views, weights and estimator (see engine/shot.h).
#include "engine/shot.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Random123/philox.h>
#include <glm/geometric.hpp>

#include "scene/emitters.h"
#include "scene/rays.h"
#include "util/error.h"

namespace sirad {

namespace {

double unit_open(uint32_t r) { return (static_cast<double>(r) + 0.5) * 0x1p-32; }

// Eight uniforms in (0, 1) for shot `index`: Philox keyed by the run seed, on the counter
// (index, stream, word) for words 0 and 1.
std::array<double, 8> shot_uniforms(uint64_t seed, uint64_t index, Stream stream) {
  r123::Philox4x32 philox;
  r123::Philox4x32::key_type key = {{static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32)}};
  std::array<double, 8> u{};
  for (uint32_t word = 0; word < 2; ++word) {
    r123::Philox4x32::ctr_type ctr = {{static_cast<uint32_t>(index), static_cast<uint32_t>(index >> 32),
                                       static_cast<uint32_t>(stream), word}};
    auto r = philox(ctr, key);
    for (int k = 0; k < 4; ++k) u[4 * word + k] = unit_open(r[k]);
  }
  return u;
}

}  // namespace

namespace {

// The emitter table of the emitting patches that `take` accepts.
template <typename Take>
EmitterTable table_of(const PatchMesh& mesh, Take take) {
  EmitterTable t;
  double total = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    if (!take(j)) continue;
    glm::dvec3 e(mesh.emission(j));
    double power = static_cast<double>(mesh.area[j]) * (e.x + e.y + e.z);
    if (!(power > 0.0)) continue;
    t.patch.push_back(static_cast<uint32_t>(j));
    t.p.push_back(power);
    total += power;
  }
  double running = 0.0;
  for (double& p : t.p) {
    p /= total;
    running += p;
    t.cdf.push_back(running);
  }
  if (!t.cdf.empty()) t.cdf.back() = 1.0;
  return t;
}

}  // namespace

EmitterTable emitter_table(const PatchMesh& mesh) {
  return table_of(mesh, [](std::size_t) { return true; });
}

EmitterTable shot_emitter_table(const PatchMesh& mesh, std::vector<double>* incoherence) {
  std::vector<int32_t> light_of;
  const std::vector<Light> lights = find_lights(mesh, &light_of);
  if (incoherence) incoherence->assign(lights.size(), 1.0);
  if (lights.empty()) return {};
  const double eps = ray_offset(mesh);
  const RayScene rays(mesh, eps, /*fast=*/true);
  const int per_light = std::max(16, std::min(kIncoherenceRays, static_cast<int>(65536 / lights.size())));
  std::vector<uint8_t> shot(lights.size(), 0);
  std::vector<std::array<double, 2>> pts, others, dirs;
  for (std::size_t l = 0; l < lights.size(); ++l) {
    const Light& light = lights[l];
    const glm::dvec3 n = light.normal;
    Rng rng(0x5407, l, 0, 5);
    stratified_square(per_light, rng, pts);
    stratified_square(per_light, rng, others);
    stratified_square(per_light, rng, dirs);
    double sum = 0.0;
    int count = 0;
    for (int k = 0; k < per_light; ++k) {
      const auto i = static_cast<std::size_t>(k);
      const glm::dvec3 y1 = light.at(pts[i][0], pts[i][1]);
      const glm::dvec3 d = cosine_direction(n, dirs[i][0], dirs[i][1]);
      const auto [hit, t] = rays.seen_at(y1 + n * eps, d);
      if (hit < 0) continue;
      const glm::dvec3 x = y1 + d * t, nx(mesh.normal[static_cast<std::size_t>(hit)]);
      // The point-to-point kernel K(y, x) = cos_y cos_x V / r^2 from the shot's point y1 and from
      // another point y2 of the light.
      const double k1 = glm::dot(n, d) * std::max(0.0, -glm::dot(nx, d)) / (t * t);
      const glm::dvec3 y2 = light.at(others[i][0], others[i][1]);
      const glm::dvec3 r = x - y2;
      const double r2 = glm::dot(r, r);
      double k2 = 0.0;
      if (r2 > 0.0) {
        const double c2 = glm::dot(n, r), cx = -glm::dot(nx, r);
        if (c2 > 0.0 && cx > 0.0 && !rays.blocked(y2 + n * eps, x + nx * eps)) k2 = c2 * cx / (r2 * r2);
      }
      if (!(k1 > 0.0) && !(k2 > 0.0)) continue;
      sum += (k2 - k1) * (k2 - k1) / (k1 * k1 + k2 * k2);
      ++count;
    }
    const double value = count > 0 ? sum / count : 1.0;
    if (incoherence) (*incoherence)[l] = value;
    shot[l] = value <= kShotIncoherence;
  }
  return table_of(mesh, [&](std::size_t j) { return light_of[j] >= 0 && shot[static_cast<std::size_t>(light_of[j])]; });
}

ShotDraw draw_shot(const PatchMesh& mesh, const EmitterTable& table, uint64_t seed, uint64_t index, Stream stream,
                   bool stratified) {
  if (table.empty()) fail("first shot: the scene has no emitting patch");
  auto u = shot_uniforms(seed, index, stream);
  ShotDraw d;
  if (stratified) {
    // The stratum of this shot in its block's random order; (u, v) uniform inside it.
    const uint64_t block = index / kShotStrata;
    const uint32_t tag = 0x60000000u | (static_cast<uint32_t>(stream) << 16);
    uint32_t stratum = block_orders(seed, block, tag, kShotStrata, 1)[index % kShotStrata];
    u[0] = (stratum % kShotStrataSide + u[0]) / kShotStrataSide;
    u[2] = (stratum / kShotStrataSide + u[2]) / kShotStrataSide;
  }
  d.emitter = static_cast<std::size_t>(std::upper_bound(table.cdf.begin(), table.cdf.end(), u[0]) - table.cdf.begin());
  d.emitter = std::min(d.emitter, table.patch.size() - 1);
  if (stratified) {
    // u's remainder inside the emitter's step of the CDF: uniform in (0, 1) given the emitter.
    double lo = d.emitter == 0 ? 0.0 : table.cdf[d.emitter - 1];
    u[1] = std::clamp((u[0] - lo) / table.p[d.emitter], 0x1p-33, 1.0 - 0x1p-33);
  }
  const uint32_t L = table.patch[d.emitter];
  const auto& tri = mesh.patches[L];
  glm::dvec3 v0(mesh.vertices[tri[0]]), v1(mesh.vertices[tri[1]]), v2(mesh.vertices[tri[2]]);
  // Uniform on the triangle (Osada et al. 2002).
  double s = std::sqrt(u[1]);
  d.eye = (1.0 - s) * v0 + s * (1.0 - u[2]) * v1 + s * u[2] * v2;
  glm::dvec3 n = glm::normalize(glm::cross(v1 - v0, v2 - v0));
  // Tangent frame (Duff et al. 2017), turned by a uniform angle about n.
  double sign = std::copysign(1.0, n.z);
  double a = -1.0 / (sign + n.z), b = n.x * n.y * a;
  glm::dvec3 t1(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), t2(b, sign + n.y * n.y * a, -n.y);
  double phi = 2.0 * std::numbers::pi * u[3];
  glm::dvec3 r1 = std::cos(phi) * t1 + std::sin(phi) * t2, r2 = -std::sin(phi) * t1 + std::cos(phi) * t2;
  d.axes[0][0] = r1;
  d.axes[0][1] = r2;
  d.axes[0][2] = n;
  const glm::dvec3 sides[4] = {r1, -r1, r2, -r2};
  for (int f = 1; f < 5; ++f) {
    const glm::dvec3& c = sides[f - 1];
    d.axes[f][0] = glm::cross(n, c);  // a x b = c with b = n
    d.axes[f][1] = n;
    d.axes[f][2] = c;
  }
  d.jitter_x = u[4];
  d.jitter_y = u[5];
  return d;
}

SiradShot make_shot(const PatchMesh& mesh, const ShotDraw& draw, int resolution) {
  if (resolution < 4 || resolution % 2 != 0 || resolution > 2048)
    fail("shot resolution must be even and in [4, 2048] (got {})", resolution);
  SiradShot s{};
  glm::dvec3 eye = draw.eye - glm::dvec3(mesh.bound_center);
  for (int k = 0; k < 3; ++k) s.eye[k] = static_cast<float>(eye[k]);
  for (int f = 0; f < 5; ++f)
    for (int m = 0; m < 3; ++m)
      for (int k = 0; k < 3; ++k) s.axes[9 * f + 3 * m + k] = static_cast<float>(draw.axes[f][m][k]);
  s.scale = static_cast<float>(resolution / 2);
  s.offset_x = static_cast<float>(resolution / 2.0 - draw.jitter_x);
  s.offset_y = static_cast<float>(resolution / 2.0 - draw.jitter_y);
  s.resolution = resolution;
  s.rows_per_band = resolution;
  s.bands_top = 1;
  s.bands_side = 1;
  s.capacity = 0;
  // Clipping at 1e-5 of the scene's radius loses only geometry that close to the eye;
  // two faces closer than 1e-5 in relative depth are one place (a thin wall's two sides).
  s.near_z = static_cast<float>(1e-5 * static_cast<double>(mesh.bound_radius));
  s.depth_tie = 1e-5f;
  return s;
}

std::size_t shot_pixels(int resolution) {
  return 3 * static_cast<std::size_t>(resolution) * static_cast<std::size_t>(resolution);
}

std::size_t shot_pixel(int resolution, int face, int y, int x) {
  const std::size_t H = static_cast<std::size_t>(resolution), half = H / 2;
  if (face == 0) return static_cast<std::size_t>(y) * H + static_cast<std::size_t>(x);
  return H * H + static_cast<std::size_t>(face - 1) * half * H + (static_cast<std::size_t>(y) - half) * H +
         static_cast<std::size_t>(x);
}

std::vector<double> shot_weights(const SiradShot& shot) {
  std::vector<double> w;
  shot_weights(shot, w);
  return w;
}

void shot_weights(const SiradShot& shot, std::vector<double>& w) {
  const int H = shot.resolution;
  w.resize(shot_pixels(H));
  const double inv = 1.0 / static_cast<double>(shot.scale), h2 = inv * inv;
  for (int f = 0; f < 5; ++f) {
    for (int y = f == 0 ? 0 : H / 2; y < H; ++y) {
      double fy = (y - static_cast<double>(shot.offset_y)) * inv;
      for (int x = 0; x < H; ++x) {
        double fx = (x - static_cast<double>(shot.offset_x)) * inv;
        double d2 = fx * fx + fy * fy + 1.0;
        double dn = f == 0 ? 1.0 : fy;  // n is face 0's c and the side faces' b
        w[shot_pixel(H, f, y, x)] = std::max(0.0, dn) * h2 / (std::numbers::pi * d2 * d2);
      }
    }
  }
}

void accumulate_shot(const PatchMesh& mesh, const EmitterTable& table, const ShotDraw& draw,
                     const SiradShot& shot, std::span<const uint32_t> image,
                     std::span<const double> weights, std::vector<glm::dvec3>& direct) {
  std::vector<double> ff;
  accumulate_shot(mesh, table, draw, shot, image, weights, direct, ff);
}

void accumulate_shot(const PatchMesh& mesh, const EmitterTable& table, const ShotDraw& draw,
                     const SiradShot& shot, std::span<const uint32_t> image,
                     std::span<const double> weights, std::vector<glm::dvec3>& direct, std::vector<double>& ff) {
  const std::size_t n = mesh.size();
  if (image.size() != shot_pixels(shot.resolution) || weights.size() != image.size() || direct.size() != n)
    fail("first shot: image of {} samples for resolution {}", image.size(), shot.resolution);
  ff.assign(n, 0.0);
  for (std::size_t i = 0; i < image.size(); ++i) {
    uint32_t j = image[i];
    if (j == SIRAD_NO_PATCH) continue;
    if (j >= n) fail("first shot: a pixel names patch {} of {}", j, n);
    ff[j] += weights[i];
  }
  const uint32_t L = table.patch[draw.emitter];
  const glm::dvec3 power = glm::dvec3(mesh.emission(L)) * (static_cast<double>(mesh.area[L]) / table.p[draw.emitter]);
  for (std::size_t j = 0; j < n; ++j)
    if (ff[j] > 0.0)
      direct[j] += glm::dvec3(mesh.reflectance(j)) * power * (ff[j] / static_cast<double>(mesh.area[j]));
}

ShotSums run_shots(const PatchMesh& mesh, ShotEngine& engine, int resolution, uint64_t seed,
                   uint64_t first, uint64_t count, Stream stream, bool stratified) {
  return run_shots(mesh, emitter_table(mesh), engine, resolution, seed, first, count, stream, stratified);
}

ShotSums run_shots(const PatchMesh& mesh, const EmitterTable& table, ShotEngine& engine, int resolution,
                   uint64_t seed, uint64_t first, uint64_t count, Stream stream, bool stratified) {
  ShotSums sums;
  ShotScratch scratch;
  run_shots(mesh, table, engine, resolution, seed, first, count, stream, stratified, sums, scratch);
  return sums;
}

void run_shots(const PatchMesh& mesh, const EmitterTable& table, ShotEngine& engine, int resolution, uint64_t seed,
               uint64_t first, uint64_t count, Stream stream, bool stratified, ShotSums& sums, ShotScratch& scratch) {
  sums.direct.assign(mesh.size(), glm::dvec3(0.0));
  sums.shots = 0;
  if (table.empty()) {
    sums.shots = count;
    return;
  }
  for (uint64_t k = first; k < first + count; ++k) {
    ShotDraw draw = draw_shot(mesh, table, seed, k, stream, stratified);
    SiradShot shot = make_shot(mesh, draw, resolution);
    engine.render(shot, scratch.image);
    shot_weights(shot, scratch.weights);
    accumulate_shot(mesh, table, draw, shot, scratch.image, scratch.weights, sums.direct, scratch.form_factors);
    ++sums.shots;
  }
}

int auto_shot_resolution(const PatchMesh& mesh) {
  if (mesh.size() == 0) return 32;
  std::vector<float> areas = mesh.area;
  auto mid = areas.begin() + areas.size() / 2;
  std::nth_element(areas.begin(), mid, areas.end());
  // A patch of area A face-on at distance r covers A / r^2 steradians; a face-0 pixel near
  // the centre (2 / H)^2: H = 4 r / sqrt(A) gives it about 4 samples.
  double h = 4.0 * static_cast<double>(mesh.bound_radius) / std::sqrt(static_cast<double>(*mid));
  int res = static_cast<int>(std::clamp(std::ceil(h / 2.0) * 2.0, 32.0, 512.0));
  return res;
}

}  // namespace sirad
