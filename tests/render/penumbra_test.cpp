// sirad tests: the final gather's light samples (render/gather.h): a penumbra is as quiet as the
// light's strata make it.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "render/gather.h"
#include "scene/camera.h"
#include "scene/emitters.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "tests/quad_scene.h"

namespace sirad {
namespace {

using test::QuadScene;

// A penumbra under a light cut into many patches is as quiet as the light's strata make it
// (scene/emitters.h): the emitter samples of a pixel's N = m x m samples are one per cell of an
// m x m grid of the light (Light::at), not spread over the patches. Scene: a floor (rho 0.5, z =
// 0) under a square light (side 0.3, E = 1, rho = 0, z = 2, cut into about 200 patches), and
// between them at z = 1 a black occluder whose edge passes over the origin at 30 degrees to the
// light's sides, covering u . p < 0 (u its edge's normal in the plane). A floor point x sees the
// light's point y iff the segment crosses z = 1 on the open side: u . (x + y) > 0. The camera
// (below the occluder) sees 0.056 x 0.056 of the floor about the origin, all of it in the
// penumbra (about half the light seen). There is no indirect light (what a gather ray meets, the
// light or the occluder, reflects nothing), every sample takes its indirect light (0) from the
// cache (one plane, its records' rays meet nothing nearer than 1, against 0.06 across the view),
// and the records' rays meet the light at most its form factor A / (pi h^2) = 0.7 % of the time,
// under the cache's 2 %: each sample's direct light is its emitter sample alone,
//   g(x, y) = rho E A cos cos / (pi r^2) <= g_max = rho E A / (pi h^2)   (h = 2).
// Its variance over seeds, a pixel's estimate D = sum_k g(x_pi(k), y_k) / N (y_k uniform in cell
// k, x_j the pixel's stratified positions, pi a random pairing), is at most (1 / N^2) times
//   sum_k Var(g | cell k) <= n_mix g_max^2 / 4 + (N - n_mix) dg^2 / 4         (the cells),
//   + N / (N - 1) sum_k range_k^2 / 4                               (the pairing: Hoeffding's
//     permutation variance, range_k the spread over x of cell k's mean: g_max * the share of
//     the cell the edge sweeps as x crosses the pixel, <= sqrt(2) w / c, for a mixed cell, dg
//     for the others),
//   + N dG^2 / 4   (the positions: the light seen moves by at most w / 16 within a position's
//     stratum, which changes the mean by at most g_max 2 sqrt(2) (w / 16) / a: dG),
// n_mix the cells the shadow's edge crosses for some point of the pixel's footprint (counted
// exactly: u . (x + y) changes sign over the cell's and the footprint's corners), w the
// footprint's extent along u, c = a / m the cell's side, and dg <= 0.01 g_max the change of g
// over a cell and a footprint where visibility does not change (|d ln g| = 4 rho d / r^2 <= 4 x
// 0.26 x 0.029 / 4 = 0.0075). Measured: 0.42 of the bound; with the samples spread over the
// light's patches (each patch a light of its own), 2.8 times the bound. The mean over the 32 x 32 pixels of the variance over 8 seeds must be within the mean of
// the bound, plus 4 standard errors of that estimate (sqrt(2 / (7 x 1024)) of it).
TEST(Gather, APenumbraIsAsQuietAsTheLightsStrata) {
  QuadScene q;
  const uint32_t floor = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
  const uint32_t light = q.material(glm::vec3(0.0f), glm::vec3(1.0f));
  const uint32_t black = q.material(glm::vec3(0.0f), glm::vec3(0.0f));
  const double a = 0.3, h = 2.0, theta = std::numbers::pi / 6.0;
  const glm::dvec3 e(std::cos(theta), std::sin(theta), 0.0), u(-std::sin(theta), std::cos(theta), 0.0);
  const float ha = static_cast<float>(a / 2);
  q.quad({-0.5f, -0.5f, 0}, {0.5f, -0.5f, 0}, {0.5f, 0.5f, 0}, {-0.5f, 0.5f, 0}, floor);                          // faces +z
  q.quad({-ha, -ha, 2}, {-ha, ha, 2}, {ha, ha, 2}, {ha, -ha, 2}, light);                                           // faces -z
  auto at1 = [](const glm::dvec3& p) { return glm::vec3(static_cast<float>(p.x), static_cast<float>(p.y), 1.0f); };
  q.quad(at1(0.5 * e), at1(0.5 * e - 0.5 * u), at1(-0.5 * e - 0.5 * u), at1(-0.5 * e), black);  // faces -z
  const PatchMesh mesh = mesh_scene(q.scene, MeshOptions{.max_edge = 0.03});
  const std::vector<Light> lights = find_lights(mesh);
  ASSERT_EQ(lights.size(), 1u);
  std::size_t light_patches = 0;
  for (std::size_t j = 0; j < mesh.size(); ++j) light_patches += mesh.emits(j);
  ASSERT_GE(light_patches, 100u) << "the light must be cut into many patches";
  std::vector<glm::vec3> solution(mesh.size(), glm::vec3(0.0f));
  for (std::size_t j = 0; j < mesh.size(); ++j)
    if (mesh.emits(j)) solution[j] = glm::vec3(1.0f);
  const Camera camera{{0, 0, 0.8f}, {0, 0, 0}, {0, 1, 0}, 4.0f};
  const int W = 32, H = 32, N = 256, m = 16, seeds = 8;
  const CameraFrame f = camera_frame(camera, W, H);
  const double g_max = 0.5 * a * a / (std::numbers::pi * h * h), dg = 0.01 * g_max, c = a / m;
  // The bound per pixel.
  std::vector<double> bound(static_cast<std::size_t>(W * H));
  auto floor_at = [&](double x, double y) {
    const glm::dvec3 d = f.direction(x, y);
    return f.eye + d * (-f.eye.z / d.z);
  };
  for (int py = 0; py < H; ++py)
    for (int px = 0; px < W; ++px) {
      const std::array<glm::dvec3, 4> foot{floor_at(px, py), floor_at(px + 1, py), floor_at(px, py + 1), floor_at(px + 1, py + 1)};
      double ux_lo = 1e9, ux_hi = -1e9;
      for (const glm::dvec3& x : foot) ux_lo = std::min(ux_lo, glm::dot(u, x)), ux_hi = std::max(ux_hi, glm::dot(u, x));
      const double w = ux_hi - ux_lo;
      int mixed = 0;
      for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) {
          double lo = 1e9, hi = -1e9;
          for (int k = 0; k < 4; ++k) {
            const double uy = glm::dot(u, lights[0].at((i + (k & 1)) / double(m), (j + (k >> 1)) / double(m)));
            lo = std::min(lo, uy + ux_lo), hi = std::max(hi, uy + ux_hi);
          }
          mixed += lo < 0.0 && hi > 0.0;
        }
      const double range_mixed = g_max * std::min(1.0, std::sqrt(2.0) * w / c), dG = g_max * 2.0 * std::sqrt(2.0) * (w / 16) / a;
      const double cells = mixed * g_max * g_max / 4 + (N - mixed) * dg * dg / 4;
      const double pairing = N / (N - 1.0) * (mixed * range_mixed * range_mixed + (N - mixed) * dg * dg) / 4;
      bound[static_cast<std::size_t>(py * W + px)] = (cells + pairing + N * dG * dG / 4) / (double(N) * N);
    }
  std::vector<double> sum(bound.size(), 0.0), sq(bound.size(), 0.0);
  for (int s = 0; s < seeds; ++s) {
    const GatherPasses p = FinalGather(mesh, solution, GatherOptions{.width = W, .height = H, .spp = N, .seed = 40u + s}).render(camera);
    for (int py = 0; py < H; ++py)
      for (int px = 0; px < W; ++px) {
        ASSERT_LE(std::abs(p.indirect.at(px, py).x), 1e-12f);  // only rounding: the light's B - E
        const double v = p.combined.at(px, py).x;
        sum[static_cast<std::size_t>(py * W + px)] += v, sq[static_cast<std::size_t>(py * W + px)] += v * v;
      }
  }
  double measured = 0.0, allowed = 0.0, mean = 0.0;
  for (std::size_t k = 0; k < bound.size(); ++k) {
    const double mu = sum[k] / seeds;
    measured += (sq[k] - seeds * mu * mu) / (seeds - 1) / static_cast<double>(bound.size());
    allowed += bound[k] / static_cast<double>(bound.size());
    mean += mu / static_cast<double>(bound.size());
  }
  EXPECT_GT(mean, 0.3 * g_max) << "the view is in the penumbra";
  EXPECT_LT(mean, 0.7 * g_max) << "the view is in the penumbra";
  EXPECT_LE(measured, allowed * (1.0 + 4.0 * std::sqrt(2.0 / ((seeds - 1) * bound.size()))));
  std::printf("penumbra: mean %.6f (g_max %.6f), variance over seeds %.3g, bound %.3g (%.2f of it)\n", mean, g_max, measured, allowed,
              measured / allowed);
}

}  // namespace
}  // namespace sirad
