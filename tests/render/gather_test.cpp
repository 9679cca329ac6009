// sirad tests: the final gather (render/gather.h): a furnace, lights over floors and walls
// against their closed forms (direct and indirect, many lights, a penumbra, a concave edge, a
// lamp under a ceiling), no light through a thin wall, and tiles and threads alike.
#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include "io/write.h"
#include "render/gather.h"
#include "scene/camera.h"
#include "scene/emitters.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "tests/closed_forms.h"
#include "tests/quad_scene.h"
#include "util/error.h"

namespace sirad {
namespace {

using test::QuadScene;
using test::floor_radiance;

// The furnace (a closed cube, every face E = 1, rho = 0.5: B = 2 everywhere, exactly) gathered
// from the exact solution, seen from inside. Each sample's value is E = 1 seen, plus rho times
// the direct estimate D (mean E = 1) and the indirect I (mean B - E = 1). With the balance
// heuristic each of D's two terms is at most E (its MIS weight over its own pdf is at most 1 over
// that pdf), so rho D lies in [0, 1]. I is the interpolated solution less E, exactly 1, unless
// the gather ray lands near (a corner): then it is rho (D' + 1) with D' in [0, 2], so rho I lies
// in [0.25, 0.75]. A sample lies in [1.25, 2.75]: variance at most 1.5^2 / 4 (Popoviciu), sd
// 0.75, and 0.1875 for a pixel of N = 16 samples. Over 32 x 32 independent pixels the image mean
// is 2 within 4 x 0.1875 / 32 = 0.0234; the pixels' RMS deviation from 2 is at most 0.1875 (1.2
// x that allows for the RMS's own spread over 1,024 pixels, about 2 %); the indirect pass (sd at
// most 0.25 a sample) has mean 0.5 within 4 x 0.0625 / 32 = 0.0078, each pixel in [0.25, 0.75].
// With the cache the pixels share records, so only the direct pass keeps those bounds: a sample's
// direct part (1 + rho D, every block weighing its emitter samples: the furnace's records meet
// emitters with every ray) lies in [1, 2], sd at most 0.5 / 4 a pixel, mean 1.5 within 4 x 0.125 /
// 32 = 0.0156. A record is the mean of 256 values of I in [0.5, 1.5] (16 spp: the fewest a record
// takes), within 0.17 of 1 but with probability 2 exp(-2 x 256 x 0.17^2) = 7.6e-7 (Hoeffding);
// all of them (at most 17 x 17 grid points 2 pixels apart) but with probability 2.2e-4. A pixel's
// indirect is rho times a mix of records (and of its own gather rays where none fits), so it lies
// in [0.25, 0.75], and the image's in 0.5 +- 0.085.
TEST(Gather, AFurnaceIsTwoEverywhere) {
  const Scene furnace = builtin_furnace();
  PatchMesh mesh = mesh_scene(furnace, MeshOptions{.target_patches = 600});
  const std::vector<glm::vec3> exact(mesh.size(), glm::vec3(2.0f));
  const Camera camera{{0.5f, 0.5f, 0.1f}, {0.6f, 0.45f, 1.0f}, {0, 1, 0}, 100.0f};  // sees walls, floor and ceiling
  for (const bool cache : {false, true}) {
    GatherOptions o{.width = 32, .height = 32, .spp = 16, .seed = 3, .cache = cache};
    GatherPasses p = FinalGather(mesh, exact, o).render(camera);
    double sum = 0.0, sq = 0.0, direct = 0.0, indirect = 0.0;
    for (std::size_t k = 0; k < p.combined.pixels.size(); ++k) {
      const glm::vec3 v = p.combined.pixels[k];
      EXPECT_EQ(v.x, v.y);  // grey: every channel the same estimate
      sum += v.x;
      sq += (v.x - 2.0) * (v.x - 2.0);
      direct += p.direct.pixels[k].x;
      indirect += p.indirect.pixels[k].x;
      EXPECT_GE(p.indirect.pixels[k].x, 0.25f - 1e-5f);
      EXPECT_LE(p.indirect.pixels[k].x, 0.75f + 1e-5f);
    }
    const double n = static_cast<double>(p.combined.pixels.size());
    if (!cache) {
      EXPECT_NEAR(sum / n, 2.0, 0.0234);
      EXPECT_LE(std::sqrt(sq / n), 0.1875 * 1.2);
      EXPECT_NEAR(indirect / n, 0.5, 0.0078);
      EXPECT_GT(p.rays, static_cast<uint64_t>(n) * 16 * 2);
      EXPECT_EQ(p.record_rays, 0u);
    } else {
      EXPECT_NEAR(direct / n, 1.5, 0.0156);
      EXPECT_NEAR(indirect / n, 0.5, 0.085);
      EXPECT_GT(p.record_rays, 0u);
    }
  }
}

// A floor (rho 0.5, the plane z = 0 within 4 of the origin, facing +z) under a square of side 1
// at height 1 facing down (x and y in [-0.5, 0.5]) of reflectance rho and emission e.
QuadScene floor_under_square(glm::vec3 rho, glm::vec3 e) {
  QuadScene q;
  const uint32_t floor = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
  const uint32_t square = q.material(rho, e);
  q.quad({-4, -4, 0}, {4, -4, 0}, {4, 4, 0}, {-4, 4, 0}, floor);                         // faces +z
  q.quad({-0.5f, -0.5f, 1}, {-0.5f, 0.5f, 1}, {0.5f, 0.5f, 1}, {0.5f, -0.5f, 1}, square);  // faces -z
  return q;
}

// The exact mean of each block of 8 x 8 pixels (row-major) of a W x H view `f` whose radiance
// along a view direction is `radiance`, from 8 x 8 points of each pixel.
void exact_block_means(const CameraFrame& f, const std::function<double(const glm::dvec3&)>& radiance, std::vector<double>& want) {
  want.assign(static_cast<std::size_t>((f.width / 8) * (f.height / 8)), 0.0);
  for (int y = 0; y < f.height; ++y)
    for (int x = 0; x < f.width; ++x)
      for (int j = 0; j < 8; ++j)
        for (int i = 0; i < 8; ++i)
          want[static_cast<std::size_t>((y / 8) * (f.width / 8) + x / 8)] += radiance(f.direction(x + (i + 0.5) / 8, y + (j + 0.5) / 8)) / (64.0 * 64.0);
}

// The means of an image's blocks of 8 x 8 pixels (red channel, row-major), over renders of
// independent seeds: each block's mean and its standard error s / sqrt(renders).
struct BlockSpread {
  std::vector<double> sum, sq;
  int renders = 0;
  void add(const Image& image) {
    const std::size_t blocks = static_cast<std::size_t>((image.width / 8) * (image.height / 8));
    sum.resize(blocks, 0.0), sq.resize(blocks, 0.0);
    std::vector<double> block(blocks, 0.0);
    for (int y = 0; y < image.height; ++y)
      for (int x = 0; x < image.width; ++x) block[static_cast<std::size_t>((y / 8) * (image.width / 8) + x / 8)] += image.at(x, y).x / 64.0;
    for (std::size_t b = 0; b < blocks; ++b) sum[b] += block[b], sq[b] += block[b] * block[b];
    ++renders;
  }
  double mean(std::size_t b) const { return sum[b] / renders; }
  double standard_error(std::size_t b) const {
    const double m = mean(b);
    return std::sqrt(std::max(0.0, (sq[b] - renders * m * m) / (renders - 1)) / renders);
  }
};

// A square light (side 1, E = 1, rho = 0) at height 1 over a floor (rho = 0.5), nothing else: a
// floor point's radiance is rho E F (closed form above); no indirect light (a gather ray from the
// floor meets the light's front, whose B - E is 0, or leaves the scene). The camera looks down at
// the floor beside the light. A pixel's expectation mu is the mean of that radiance over the
// pixel (8 x 8 points of it, where its rays meet the floor). Per sample the direct estimate D is
// at most 2 M, M = rho E A / (pi r_min^2) with r_min the pixel's least distance to the light
// (each MIS term is at most rho E cos cos A / (pi r^2)), so Var D <= E[D^2] <= 2 M mu; a region
// of pixels of N samples each has variance at most sum(2 M mu / N) / pixels^2. Each 8 x 8 block
// (per region, not only the whole image) and the whole image must lie within 4 sd of it.
TEST(Gather, ASquareLightOverAFloorMatchesItsClosedForm) {
  const QuadScene q = floor_under_square(glm::vec3(0.0f), glm::vec3(1.0f));
  PatchMesh mesh = mesh_scene(q.scene, MeshOptions{});
  std::vector<glm::vec3> solution(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) solution[j] = mesh.emits(j) ? glm::vec3(1.0f) : glm::vec3(0.01f);
  const Camera camera{{2.5f, 0, 1.2f}, {2.5f, 0, 0}, {1, 0, 0}, 60.0f};
  const int W = 32, H = 32, N = 256;
  GatherOptions o{.width = W, .height = H, .spp = N, .seed = 11};
  GatherPasses p = FinalGather(mesh, solution, o).render(camera);
  const CameraFrame f = camera_frame(camera, W, H);
  std::vector<double> mu(static_cast<std::size_t>(W) * H), var(mu.size());
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      double sum = 0.0, r_min = 1e9;
      for (int j = 0; j <= 8; ++j)
        for (int i = 0; i <= 8; ++i) {
          const glm::dvec3 d = f.direction(x + i / 8.0, y + j / 8.0);
          ASSERT_LT(d.z, 0.0);
          const glm::dvec3 hit = f.eye + d * (-f.eye.z / d.z);
          // The pixel's 8 x 8 cell centres for the mean; its 9 x 9 cell corners (its whole
          // footprint: the distance to the light is monotone along each side) for r_min.
          if (i < 8 && j < 8) {
            const glm::dvec3 c = f.direction(x + (i + 0.5) / 8, y + (j + 0.5) / 8);
            const glm::dvec3 at = f.eye + c * (-f.eye.z / c.z);
            sum += floor_radiance(at.x, at.y, -0.5, 0.5, -0.5, 0.5, 1.0, 0.5, 1.0);
          }
          const double dx = std::max(0.0, std::abs(hit.x) - 0.5), dy = std::max(0.0, std::abs(hit.y) - 0.5);
          r_min = std::min(r_min, std::sqrt(dx * dx + dy * dy + 1.0));
        }
      const std::size_t k = static_cast<std::size_t>(y) * W + x;
      mu[k] = sum / 64;
      var[k] = 2.0 * (0.5 * 1.0 * 1.0 / (std::numbers::pi * r_min * r_min)) * mu[k] / N;
    }
  double all_got = 0.0, all_want = 0.0, all_var = 0.0;
  for (int by = 0; by < H; by += 8)
    for (int bx = 0; bx < W; bx += 8) {
      double got = 0.0, want = 0.0, v = 0.0;
      for (int y = by; y < by + 8; ++y)
        for (int x = bx; x < bx + 8; ++x) {
          const std::size_t k = static_cast<std::size_t>(y) * W + x;
          got += p.combined.at(x, y).x;
          want += mu[k];
          v += var[k];
          EXPECT_EQ(p.indirect.at(x, y).x, 0.0f);
        }
      EXPECT_NEAR(got / 64.0, want / 64.0, 4.0 * std::sqrt(v) / 64.0) << "block " << bx << ", " << by;
      all_got += got, all_want += want, all_var += v;
    }
  const double n = static_cast<double>(W) * H;
  EXPECT_NEAR(all_got / n, all_want / n, 4.0 * std::sqrt(all_var) / n);
  std::printf("square light: image mean %.6f, closed form %.6f, 4 sd %.6f\n", all_got / n, all_want / n, 4.0 * std::sqrt(all_var) / n);
}

// The form factor from a point x with normal n to a polygon (Lambert's formula, exact where the
// whole polygon lies in front of x): |sum over edges of beta_i n . gamma_i| / (2 pi), beta_i the
// angle the edge subtends at x and gamma_i the unit normal of the plane through x and the edge.
double polygon_form_factor(const glm::dvec3& x, const glm::dvec3& n, const std::vector<glm::dvec3>& polygon) {
  double sum = 0.0;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const glm::dvec3 a = glm::normalize(polygon[i] - x), b = glm::normalize(polygon[(i + 1) % polygon.size()] - x);
    sum += std::acos(std::clamp(glm::dot(a, b), -1.0, 1.0)) * glm::dot(n, glm::normalize(glm::cross(a, b)));
  }
  return std::abs(sum) / (2.0 * std::numbers::pi);
}

// A wall meeting a ceiling light's plane at a right angle (the walls of a room under a ceiling
// light, which see it at grazing angles): the square light of side 1 (E = 1, rho = 0) at height
// 1 facing down, the wall (rho = 0.5) the plane x = 1 facing -x, up to the light's height. A wall
// point's radiance is rho E F, F the form factor to the square (Lambert's formula above); as in
// the floor test there is no indirect light, and the camera sees the wall's upper part (z from
// 0.04 to 0.96, where F falls to nearly 0 at the ceiling). The tolerance is the images' own
// spread: R = 16 renders of independent seeds give each 8 x 8 block's mean and its standard error
// s / sqrt(R); the block's mean must lie within 6 standard errors of the exact value (Student's
// t with 15 degrees of freedom exceeds 6 with probability 2.4e-5). The images are stratified, so
// that error is about 0.05 %: a light sampled or weighted wrong at grazing angles, or a shadow ray
// that grazes the light's plane and is blocked, is off by more.
TEST(Gather, AWallBesideACeilingLightMatchesLambertsFormula) {
  QuadScene q;
  const uint32_t wall = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
  const uint32_t light = q.material(glm::vec3(0.0f), glm::vec3(1.0f));
  q.quad({1, -2, 0}, {1, -2, 1}, {1, 2, 1}, {1, 2, 0}, wall);                             // faces -x
  q.quad({-0.5f, -0.5f, 1}, {-0.5f, 0.5f, 1}, {0.5f, 0.5f, 1}, {0.5f, -0.5f, 1}, light);  // faces -z
  PatchMesh mesh = mesh_scene(q.scene, MeshOptions{});
  ASSERT_LT(glm::dot(mesh.normal[0], glm::vec3(1, 0, 0)), -0.99f);
  std::vector<glm::vec3> solution(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) solution[j] = mesh.emits(j) ? glm::vec3(1.0f) : glm::vec3(0.01f);
  const Camera camera{{0.2f, 0, 0.5f}, {1, 0, 0.5f}, {0, 0, 1}, 60.0f};
  constexpr int W = 32, H = 32, N = 256, R = 16;
  const CameraFrame f = camera_frame(camera, W, H);
  const std::vector<glm::dvec3> square{{-0.5, -0.5, 1}, {-0.5, 0.5, 1}, {0.5, 0.5, 1}, {0.5, -0.5, 1}};
  std::vector<double> want;
  bool on_wall = true;
  exact_block_means(f, [&](const glm::dvec3& d) {
    const glm::dvec3 at = f.eye + d * ((1.0 - f.eye.x) / d.x);
    on_wall = on_wall && at.z > 0.0 && at.z < 1.0 && std::abs(at.y) < 2.0;
    return 0.5 * 1.0 * polygon_form_factor(at, {-1, 0, 0}, square);
  }, want);
  ASSERT_TRUE(on_wall) << "a pixel sees past the wall";
  BlockSpread spread;
  for (int r = 0; r < R; ++r) {
    GatherOptions o{.width = W, .height = H, .spp = N, .seed = static_cast<uint64_t>(13 + r)};
    const GatherPasses p = FinalGather(mesh, solution, o).render(camera);
    spread.add(p.combined);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        EXPECT_NEAR(p.indirect.at(x, y).x, 0.0f, 1e-6f);  // B - E of the light: 0 but for the interpolation's rounding
  }
  double worst = 0.0;
  for (std::size_t b = 0; b < want.size(); ++b) {
    const double mean = spread.mean(b), se = spread.standard_error(b);
    EXPECT_NEAR(mean, want[b], 6.0 * se) << "block " << b;
    worst = std::max(worst, std::abs(mean / want[b] - 1.0));
    std::printf("block %zu: %.6f, Lambert %.6f, standard error %.3f %%\n", b, mean, want[b], 100.0 * se / want[b]);
  }
  std::printf("wall beside a ceiling light: worst block %.3f %% off\n", 100.0 * worst);
}

// The indirect light against its closed form, where the cache interpolates a light that peaks: a
// floor (rho 0.5) under a square (side 1, height 1, facing down) that emits nothing but whose
// solution is B = 1, and no emitter. A floor point's radiance is then all indirect, rho B F with F
// its form factor to the square (tests/closed_forms.h floor_radiance): the gather rays that meet the square
// take B - E = 1 there (they land at least 1 away, beyond the near bounce of kNear = 4 patch
// sizes: the square's patches are 0.1 across), the others leave the scene (background 0). Seen
// from above, the image spans the peak under the square and its fall beyond the square's edge.
// As in the wall test, R = 12 renders of independent seeds give each 8 x 8 block's mean and
// standard error (a cache record's error included: records are independent per seed); each
// block's mean must lie within 6 standard errors of the exact mean (Student's t with 11 degrees
// of freedom exceeds 6 with probability 9e-5). The cache may add its interpolation's bias: over a
// block of side h (bilinear, and linear in world space on a plane seen by a pinhole) at most
// h^2 / 8 (|f_xx| + |f_yy|) for f = rho F, and its blocks here are at most h across: 0.25 /
// sqrt(2) (corners at most kCacheWard = 0.25 of the least gather distance apart, and every ray
// that meets the square goes at least 1) or 4 pixels (taken at any distance), whichever is more;
// the second derivatives are the closed form's, largest over the floor in view. The harmonic
// mean distance that Ward took would let blocks span the whole view here (most rays leave the
// scene), 15 % off at the peak.
TEST(Gather, TheIndirectLightUnderALitSquareMatchesItsClosedForm) {
  const QuadScene q = floor_under_square(glm::vec3(0.5f), glm::vec3(0.0f));
  PatchMesh mesh = mesh_scene(q.scene, MeshOptions{.target_patches = 4000});
  std::vector<glm::vec3> solution(mesh.size());
  std::size_t on_square = 0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const bool up = mesh.normal[j].z < -0.5f;
    solution[j] = up ? glm::vec3(1.0f) : glm::vec3(0.0f);
    if (up) {
      ++on_square;
      ASSERT_LT(4.0 * std::sqrt(2.0 * mesh.area[j]), 0.99) << "a gather ray from the floor to the square must not take the near bounce";
    }
  }
  ASSERT_GT(on_square, 0u);
  const Camera camera{{0.7f, 0, 0.8f}, {0.7f, 0, 0}, {1, 0, 0}, 90.0f};
  constexpr int W = 32, H = 32, R = 12;
  const CameraFrame f = camera_frame(camera, W, H);
  auto radiance = [](double x, double y) { return floor_radiance(x, y, -0.5, 0.5, -0.5, 0.5, 1.0, 0.5, 1.0); };
  double curvature = 0.0;  // max |f_xx| + |f_yy| over the floor in view (central differences)
  constexpr double step = 1e-3;
  for (double x = -0.2; x <= 1.7; x += 0.01)
    for (double y = -0.9; y <= 0.9; y += 0.01) {
      const double c = radiance(x, y);
      curvature = std::max(curvature, std::abs(radiance(x + step, y) - 2 * c + radiance(x - step, y)) / (step * step) +
                                          std::abs(radiance(x, y + step) - 2 * c + radiance(x, y - step)) / (step * step));
    }
  const double pixel = 2.0 * 0.8 * std::tan(45.0 * std::numbers::pi / 180.0) / W;  // on the floor, 0.8 below the eye
  const double h = std::max(0.25 / std::sqrt(2.0), 4.0 * pixel), interpolation = h * h / 8.0 * curvature;
  std::vector<double> want;
  bool in_view = true;  // within the floor over which the curvature was taken
  exact_block_means(f, [&](const glm::dvec3& d) {
    const glm::dvec3 at = f.eye + d * (-f.eye.z / d.z);
    in_view = in_view && at.x > -0.2 && at.x < 1.7 && std::abs(at.y) < 0.9;
    return radiance(at.x, at.y);
  }, want);
  ASSERT_TRUE(in_view);
  std::printf("interpolation bound %.6f (%.2f %% of the peak)\n", interpolation, 100.0 * interpolation / radiance(0, 0));
  for (const bool cache : {true, false}) {
    BlockSpread spread;
    uint64_t record_rays = 0;
    for (int r = 0; r < R; ++r) {
      GatherOptions o{.width = W, .height = H, .spp = 64, .seed = static_cast<uint64_t>(41 + r), .cache = cache};
      const GatherPasses p = FinalGather(mesh, solution, o).render(camera);
      record_rays += p.record_rays;
      spread.add(p.combined);
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) EXPECT_EQ(p.direct.at(x, y).x, 0.0f);
    }
    EXPECT_EQ(record_rays > 0, cache);
    double worst = 0.0;
    for (std::size_t b = 0; b < want.size(); ++b) {
      const double mean = spread.mean(b), se = spread.standard_error(b);
      EXPECT_NEAR(mean, want[b], 6.0 * se + (cache ? interpolation : 0.0)) << "block " << b << (cache ? ", cache" : ", no cache");
      worst = std::max(worst, std::abs(mean / want[b] - 1.0));
      std::printf("%s block %zu: %.6f, closed form %.6f, standard error %.3f %%\n", cache ? "cache" : "rays", b, mean, want[b], 100.0 * se / want[b]);
    }
    std::printf("indirect under a square, %s: worst block %.3f %% off\n", cache ? "cache" : "no cache", 100.0 * worst);
  }
}

// Many lights, each pixel's emitter samples choosing among them by what they send it
// (Impl::choice in render/gather.cpp): a floor (rho 0.5, z = 0) under 16 square lights (side 0.25, E = 1,
// rho = 0, facing down at height 1, a 4 x 4 grid 1 apart), seen from below them straight down.
// A floor point's radiance is the sum of the lights' closed forms (floor_radiance); there is no
// indirect light (the lights reflect nothing). The choice must leave the estimate unbiased,
// with the gather rays that meet a light weighed by the same choice's pdf: with and without the
// cache, R = 12 renders of independent seeds, each 8 x 8 block's mean within 6 standard errors
// of its exact mean (Student's t with 11 degrees of freedom, as in the wall test). The light
// right above a pixel brings most of its light; chosen by area it would have 1/16 of the
// samples (the figures printed: the blocks' standard errors).
TEST(Gather, ManyLightsChosenByWhatTheySendMatchTheirClosedForm) {
  QuadScene q;
  const uint32_t floor = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
  const uint32_t lamp = q.material(glm::vec3(0.0f), glm::vec3(1.0f));
  q.quad({-4, -4, 0}, {4, -4, 0}, {4, 4, 0}, {-4, 4, 0}, floor);
  std::vector<std::array<double, 2>> centres;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      const float cx = -1.5f + i, cy = -1.5f + j, h = 0.125f;
      q.quad({cx - h, cy - h, 1}, {cx - h, cy + h, 1}, {cx + h, cy + h, 1}, {cx + h, cy - h, 1}, lamp);  // faces -z
      centres.push_back({cx, cy});
    }
  const PatchMesh mesh = mesh_scene(q.scene, MeshOptions{.target_patches = 3000});
  ASSERT_EQ(find_lights(mesh).size(), 16u);
  std::vector<glm::vec3> solution(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) solution[j] = mesh.emits(j) ? glm::vec3(1.0f) : glm::vec3(0.02f);
  const Camera camera{{0, 0, 0.9f}, {0, 0, 0}, {0, 1, 0}, 90.0f};  // the floor's [-0.9, 0.9]^2, under four lights
  constexpr int W = 32, H = 32, R = 12;
  const CameraFrame f = camera_frame(camera, W, H);
  std::vector<double> want;
  exact_block_means(f, [&](const glm::dvec3& d) {
    const glm::dvec3 at = f.eye + d * (-f.eye.z / d.z);
    double sum = 0.0;
    for (const auto& c : centres) sum += floor_radiance(at.x, at.y, c[0] - 0.125, c[0] + 0.125, c[1] - 0.125, c[1] + 0.125, 1.0, 0.5, 1.0);
    return sum;
  }, want);
  for (const bool cache : {false, true}) {
    BlockSpread spread;
    for (int r = 0; r < R; ++r) {
      const GatherPasses p = FinalGather(mesh, solution, GatherOptions{.width = W, .height = H, .spp = 64, .seed = static_cast<uint64_t>(71 + r), .cache = cache}).render(camera);
      spread.add(p.combined);
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) ASSERT_LE(std::abs(p.indirect.at(x, y).x), 1e-9f);  // only rounding: the lights' B - E
    }
    double worst = 0.0, se_sum = 0.0;
    for (std::size_t b = 0; b < want.size(); ++b) {
      const double mean = spread.mean(b), se = spread.standard_error(b);
      EXPECT_NEAR(mean, want[b], 6.0 * se) << "block " << b << (cache ? ", cache" : ", no cache");
      worst = std::max(worst, std::abs(mean - want[b]) / se);
      se_sum += se / want[b] / static_cast<double>(want.size());
    }
    std::printf("many lights, %s: worst block %.2f standard errors off, mean standard error %.3f %% of a block\n",
                cache ? "cache" : "no cache", worst, 100.0 * se_sum);
  }
}

// The cache does not carry light through a thin wall. Two rooms' floors (rho 0.5) lie in one
// plane, z = 0, either side of a wall 0.014 thick and 1 high (x in [0.021, 0.035]); a light over
// room A (x < 0) lights its floor and the wall's A side, which the solution says are bright (1),
// room B's floor and wall side dark (0). Seen from high above (64 x 64 pixels, 0.6 across at
// the floor, nearly square on), the wall's top falls between the cache's grid points at raster
// x = 34 (floor A) and 36 (floor B): a block whose corners were taken because they are one
// plane would give room B's floor beside the wall the light of room A's. Right of the wall's A
// side (as the camera sees it: x > 0.021 x 30 / 29 on the floor), what a sample sees (the wall's
// top, floor B) has no indirect light: a gather ray from there meets the light (B - E = 0), the
// dark side or nothing, and so does the bounce further. Without the cache and with it, every
// pixel there must have an indirect light of 0.
TEST(Gather, TheCacheDoesNotCarryLightThroughAThinWall) {
  QuadScene q;
  const uint32_t white = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
  const uint32_t light = q.material(glm::vec3(0.0f), glm::vec3(5.0f));
  const float w0 = 0.021f, w1 = 0.035f, eye = 30.0f;
  q.quad({-2, -1, 0}, {w0, -1, 0}, {w0, 1, 0}, {-2, 1, 0}, white);        // floor A, faces +z
  q.quad({w1, -1, 0}, {2, -1, 0}, {2, 1, 0}, {w1, 1, 0}, white);          // floor B
  q.quad({w0, -1, 0}, {w0, -1, 1}, {w0, 1, 1}, {w0, 1, 0}, white);        // the wall's A side, faces -x
  q.quad({w1, -1, 0}, {w1, 1, 0}, {w1, 1, 1}, {w1, -1, 1}, white);        // its B side, faces +x
  q.quad({w0, -1, 1}, {w1, -1, 1}, {w1, 1, 1}, {w0, 1, 1}, white);        // its top, faces +z
  q.quad({-1.5f, -0.5f, 1.5f}, {-1.5f, 0.5f, 1.5f}, {-0.5f, 0.5f, 1.5f}, {-0.5f, -0.5f, 1.5f}, light);  // faces -z
  const PatchMesh mesh = mesh_scene(q.scene, MeshOptions{.max_edge = 0.05});
  std::vector<glm::vec3> solution(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const auto& p = mesh.patches[j];
    const float cx = (mesh.vertices[p[0]].x + mesh.vertices[p[1]].x + mesh.vertices[p[2]].x) / 3.0f;
    solution[j] = mesh.emits(j) ? glm::vec3(5.0f) : glm::vec3(cx < w0 + 0.001f ? 1.0f : 0.0f);
  }
  const double half = 0.3;
  const Camera camera{{0, 0, eye}, {0, 0, 0}, {0, 1, 0}, static_cast<float>(2.0 * std::atan(half / eye) * 180.0 / std::numbers::pi)};
  const int W = 64, H = 64;
  const double a_side = w0 * eye / (eye - 1.0);  // where the A side's top edge is seen, on the floor
  for (bool cache : {false, true}) {
    const GatherPasses p = FinalGather(mesh, solution, GatherOptions{.width = W, .height = H, .spp = 64, .seed = 3, .cache = cache}).render(camera);
    double beside_a = 0.0;
    int right = 0;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const double left = -half + 2.0 * half * x / W;  // the pixel's footprint on the floor, x
        if (left > a_side) {
          ++right;
          EXPECT_LE(std::abs(p.indirect.at(x, y).x), 1e-9f) << "pixel " << x << ", " << y << (cache ? ", cache" : ", no cache");  // rounding only
        }
        if (left + 2.0 * half / W < w0 && left + 4.0 * half / W > w0) beside_a += p.indirect.at(x, y).x / H;
      }
    EXPECT_GT(right, 25 * H);
    EXPECT_GT(beside_a, 0.05) << "room A's floor beside the wall has indirect light";
    std::printf("thin wall, %s: room A's floor beside the wall %.4f\n", cache ? "cache" : "no cache", beside_a);
  }
}

// For the straight-down views of the two tests below (W = H = 32, up +x): where the ray through
// the middle of raster row y meets the floor z = 0, along x.
constexpr int kFloorW = 32, kFloorH = 32;
double camera_ray_floor_x(const Camera& camera, double y) {
  const CameraFrame f = camera_frame(camera, kFloorW, kFloorH);
  return f.eye.x + f.direction(16, y).x * (-f.eye.z / f.direction(16, y).z);
}

// Rows first .. first + rows - 1 of that view of a floor (z = 0, rho 0.5, facing +z) whose only
// light is the solution's B = 1 on the polygon `face` (which reflects nothing), where the floor
// lies at x > 0 (elsewhere the view sees nothing lit). A floor point's radiance is rho F, F its
// form factor to `face` (Lambert's formula), and each row's exact mean comes from 8 x 8 points of
// each pixel. Each row's mean over R = 8 renders of independent seeds (seed0, ...) at 256 spp
// must lie within 6 standard errors of it (Student's t with 7 degrees of freedom exceeds 6 with
// probability 5e-4 per row), with and without the cache (which casts record rays only when on).
void expect_rows_match_lambert(const PatchMesh& mesh, const std::vector<glm::vec3>& solution, const Camera& camera,
                               const std::vector<glm::dvec3>& face, int first, int rows, uint64_t seed0, const char* what) {
  constexpr int R = 8, spp = 256;
  const CameraFrame f = camera_frame(camera, kFloorW, kFloorH);
  auto radiance = [&](const glm::dvec3& d) {
    const glm::dvec3 at = f.eye + d * (-f.eye.z / d.z);
    return at.x > 0.0 ? 0.5 * polygon_form_factor(at, {0, 0, 1}, face) : 0.0;
  };
  std::vector<double> want(static_cast<std::size_t>(rows), 0.0);
  for (int r = 0; r < rows; ++r)
    for (int x = 0; x < kFloorW; ++x)
      for (int j = 0; j < 8; ++j)
        for (int i = 0; i < 8; ++i)
          want[static_cast<std::size_t>(r)] += radiance(f.direction(x + (i + 0.5) / 8, first + r + (j + 0.5) / 8)) / (64.0 * kFloorW);
  for (const bool cache : {true, false}) {
    std::vector<double> sum(want.size(), 0.0), sq(want.size(), 0.0);
    uint64_t record_rays = 0;
    for (int k = 0; k < R; ++k) {
      const GatherPasses p = FinalGather(mesh, solution,
                                         GatherOptions{.width = kFloorW, .height = kFloorH, .spp = spp, .seed = seed0 + static_cast<uint64_t>(k), .cache = cache})
                                 .render(camera);
      record_rays += p.record_rays;
      for (int r = 0; r < rows; ++r) {
        double row = 0.0;
        for (int x = 0; x < kFloorW; ++x) row += p.combined.at(x, first + r).x / kFloorW;
        sum[static_cast<std::size_t>(r)] += row, sq[static_cast<std::size_t>(r)] += row * row;
      }
    }
    EXPECT_EQ(record_rays > 0, cache);
    for (std::size_t r = 0; r < want.size(); ++r) {
      const double mean = sum[r] / R, se = std::sqrt(std::max(0.0, (sq[r] - R * mean * mean) / (R - 1)) / R);
      EXPECT_NEAR(mean, want[r], 6.0 * se) << what << ", row " << first + static_cast<int>(r) << (cache ? ", cache" : ", no cache");
      std::printf("%s, %s, row %zu: %.6f, closed form %.6f (%+.2f %%), standard error %.3f %%\n", what, cache ? "cache" : "no cache",
                  first + r, mean, want[r], 100.0 * (mean / want[r] - 1.0), 100.0 * se / want[r]);
    }
  }
}

// The indirect light beside a concave edge, where the cache's grid would extrapolate: a floor
// (rho 0.5, z = 0, x > 0) meeting a low wall (x = 0, facing +x, height 0.1) that reflects nothing
// but whose solution is B = 1. A floor point's radiance is all indirect, rho B F with F its form
// factor to the wall (Lambert's formula): the gather rays that meet the wall take B - E = 1 there
// (it reflects nothing, so no near bounce), the others leave the scene. F falls from 0.5 at the
// edge to 0.16 one wall height away. The camera looks straight down, the edge along a pixel row's
// middle (raster y 23.5 of 32), so that rows 22 and 23 are a block of kCacheLeast pixels whose
// corners are not one surface (row 22 on the floor, row 24 on the wall): an edge. Taking the
// corners of their own surface, the floor's samples there would take row 22's records, F = 0.16
// at x = 0.094, for points down to x = 0 where F is 0.5: the two rows 35 % and 63 % dark (the
// bias of the Cornell box's edges, smaller there, bench/RESULTS.md). From 256 spp (kEdgeSpp) they
// gather for themselves, unbiased. Each of the two rows' mean over R = 8 renders of independent seeds must lie within 6
// standard errors of its exact mean (Student's t with 7 degrees of freedom exceeds 6 with
// probability 5e-4 per row), with and without the cache.
TEST(Gather, TheIndirectLightBesideAConcaveEdgeMatchesItsClosedForm) {
  QuadScene q;
  const uint32_t floor = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
  const uint32_t wall = q.material(glm::vec3(0.0f), glm::vec3(0.0f));
  const float height = 0.1f;
  q.quad({0, -3, 0}, {2, -3, 0}, {2, 3, 0}, {0, 3, 0}, floor);              // faces +z
  q.quad({0, -3, 0}, {0, 3, 0}, {0, 3, height}, {0, -3, height}, wall);     // faces +x
  PatchMesh mesh = mesh_scene(q.scene, MeshOptions{.target_patches = 2000});
  std::vector<glm::vec3> solution(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) solution[j] = mesh.normal[j].x > 0.5f ? glm::vec3(1.0f) : glm::vec3(0.0f);
  // Straight down from height 1 with a 90 degree field of view: raster y = 16 (1 - (x - eye x)) at
  // W = H = 32 (up is +x), so the edge x = 0 lies at y = 23.5 for eye x = 0.46875.
  const float eye_x = 0.46875f;
  const Camera camera{{eye_x, 0, 1}, {eye_x, 0, 0}, {1, 0, 0}, 90.0f};
  ASSERT_NEAR(camera_ray_floor_x(camera, 23.5), 0.0, 1e-9) << "the edge lies mid-row";
  expect_rows_match_lambert(mesh, solution, camera, {{0, -3, 0}, {0, 3, 0}, {0, 3, height}, {0, -3, height}}, 22, 2, 71, "beside an edge");
}

// The indirect light beside a lamp hung 1.5 cm under a ceiling, where the light that leaves the gap
// falls off within centimetres: a floor (rho 0.5, z = 0, x > 0, facing +z) beside a lid at
// height h = 0.015 over x < 0 facing down, which reflects nothing but whose solution is B = 1. A
// floor point at distance d from the lid's edge takes rho F, F = (1 - d / sqrt(d^2 + h^2)) / 2
// (Lambert's formula: 0.14 at 1.6 cm, 0.003 at 14 cm). The camera looks straight down, pixels 6 cm
// wide, the edge a quarter pixel past the records' row y = 16 (raster y = 16.25): the block of
// rows 12..16 has a corner of 0.14 and one of 0.0008. Interpolated between them, rows 13-15
// came out 8.0, 9.6 and 2.9 times their exact values (measured without kCacheContrast); blocks
// whose corners differ more than twofold are refined, and at 2 pixels (from 256 spp) gather for
// themselves. Each row's mean over R = 8 renders within 6 standard errors of its exact mean, as
// in the test above, with and without the cache.
TEST(Gather, TheIndirectLightBesideALampUnderACeilingMatchesItsClosedForm) {
  QuadScene q;
  const uint32_t floor = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
  const uint32_t lid = q.material(glm::vec3(0.0f), glm::vec3(0.0f));
  const float h = 0.015f;
  q.quad({0, -3, 0}, {3, -3, 0}, {3, 3, 0}, {0, 3, 0}, floor);   // faces +z
  q.quad({-3, -3, h}, {-3, 3, h}, {0, 3, h}, {0, -3, h}, lid);    // faces -z
  PatchMesh mesh = mesh_scene(q.scene, MeshOptions{.target_patches = 2000});
  std::vector<glm::vec3> solution(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) solution[j] = mesh.normal[j].z < -0.5f ? glm::vec3(1.0f) : glm::vec3(0.0f);
  // Straight down from height 1, 90 degrees, W = H = 32, up +x: raster y = 16 (1 - (x - eye x)),
  // so the edge x = 0 lies at y = 16.25 for eye x = 1 / 64.
  const float eye_x = 0.015625f;
  const Camera camera{{eye_x, 0, 1}, {eye_x, 0, 0}, {1, 0, 0}, 90.0f};
  ASSERT_NEAR(camera_ray_floor_x(camera, 16.25), 0.0, 1e-9) << "the edge";
  expect_rows_match_lambert(mesh, solution, camera, {{-3, -3, h}, {-3, 3, h}, {0, 3, h}, {0, -3, h}}, 13, 3, 91, "beside a lamp's gap");
}

// Tiles: any split of the image, on any number of threads, is the same image bit for bit.
TEST(Gather, TilesAndThreadsGiveTheSameImage) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), MeshOptions{.target_patches = 300});
  std::vector<glm::vec3> radiosity(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) radiosity[j] = mesh.emission(j) + mesh.reflectance(j) * 3.0f;
  // 256 spp: an edge's samples gather for themselves, 8 rays each (kEdgeSpp in render/gather.cpp).
  for (const int spp : {4, 256}) {
    SCOPED_TRACE(fmt::format("{} spp", spp));
    GatherOptions o{.width = 24, .height = 20, .spp = spp, .seed = 5, .threads = 2};
    FinalGather whole(mesh, radiosity, o);
    const GatherPasses a = whole.render(*mesh.camera);
    o.threads = 1;
    FinalGather one(mesh, radiosity, o);
    GatherPasses b = a;
    for (Image* image : {&b.direct, &b.indirect, &b.combined}) std::fill(image->pixels.begin(), image->pixels.end(), glm::vec3(-1.0f));
    b.rays = 0;
    for (int y = 0; y < 20; y += 7)
      for (int x = 0; x < 24; x += 5) {
        const int x1 = std::min(x + 5, 24), y1 = std::min(y + 7, 20);
        const GatherPasses t = one.render(*mesh.camera, x, y, x1, y1);
        ASSERT_EQ(t.combined.width, x1 - x) << "a region's passes are of its size";
        ASSERT_EQ(t.combined.height, y1 - y);
        for (int ty = y; ty < y1; ++ty)
          for (int tx = x; tx < x1; ++tx) {
            b.direct.at(tx, ty) = t.direct.at(tx - x, ty - y);
            b.indirect.at(tx, ty) = t.indirect.at(tx - x, ty - y);
            b.combined.at(tx, ty) = t.combined.at(tx - x, ty - y);
          }
        b.rays += t.rays;
      }
    EXPECT_EQ(a.combined.pixels, b.combined.pixels);
    EXPECT_EQ(a.direct.pixels, b.direct.pixels);
    EXPECT_EQ(a.indirect.pixels, b.indirect.pixels);
    EXPECT_EQ(a.rays, b.rays);
    EXPECT_GT(a.record_rays, 0u);  // the cache was on
  }
  FinalGather one(mesh, radiosity, GatherOptions{.width = 24, .height = 20, .spp = 4, .seed = 5, .threads = 1});
  EXPECT_THROW(one.render(*mesh.camera, 0, 0, 25, 1), Error);
  EXPECT_THROW(one.render(*mesh.camera, 3, 0, 2, 1), Error);
  EXPECT_THROW(FinalGather(mesh, radiosity, GatherOptions{.spp = 0}), Error);
}

}  // namespace
}  // namespace sirad
