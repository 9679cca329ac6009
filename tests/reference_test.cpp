// sirad tests: the independent reference solver (core/reference.h): exact cases (furnace, closed
// form factors with and without an occluder), calibration of its standard error, agreement of
// the bundle solver with it, and its command line and file. Tolerances are derived beside each
// test; seeds are fixed, so every test is deterministic.
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/reference.h"
#include "tests/test_util.h"

namespace sirad {
namespace {

namespace fs = std::filesystem;
using glm::dvec3;

bool emits(const PatchMesh& mesh, std::size_t j) {
  glm::vec3 e = mesh.emission(j);
  return e.x > 0 || e.y > 0 || e.z > 0;
}

// Furnace: closed cube, E = 1, rho = 0.5: B = 2 exactly. Every row of the estimated F sums to 1
// exactly (every ray from inside a closed cube hits a front face), and the direct part is
// rho * sum_L F_analytic(x, L) * 1 = 0.5 exactly (the contour form factors of the five other
// faces of a convex box sum to 1 at every point; no shadow ray is blocked), so each batch solves
// Y = 0.5 + 0.5 F Y with F stochastic: Y = 1. What remains is rounding: F's weights are floats
// (1e-7 relative) amplified by 1 / (1 - rho) = 2, and the solver stops at 1e-12: bound 1e-5.
TEST(ReferenceFurnace, IsExactlyTwo) {
  PatchMesh mesh = mesh_scene(builtin_furnace(), {.target_patches = 400});
  ReferenceSolution s = solve_reference(mesh, {.rays_per_patch = 256, .light_samples = 16, .batches = 4, .seed = 3});
  std::printf("furnace: %zu patches, %llu rays, %.3f s, %d sweeps\n", mesh.size(),
              static_cast<unsigned long long>(s.rays), s.seconds, s.iterations);
  ASSERT_EQ(s.radiosity.size(), mesh.size());
  EXPECT_TRUE(s.converged);
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    for (int c = 0; c < 3; ++c) {
      ASSERT_NEAR(s.radiosity[j][c], 2.0, 1e-5) << "patch " << j << " channel " << c;
      ASSERT_NEAR(s.direct[j][c], 0.5, 1e-9) << "patch " << j << " channel " << c;
      ASSERT_LT(s.radiosity_se[j][c], 1e-5) << "patch " << j;
    }
  }
}

// Two squares facing each other (or meeting at an edge), the upper one emitting E = (1, 2, 3),
// the receiver rho = 0.5, optionally a square occluder between them. Unit squares, coordinates
// exactly representable in float, so the mesh is the exact geometry.
Scene two_squares(bool perpendicular, bool occluder) {
  std::string obj = "mtllib m.mtl\nusemtl receiver\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nusemtl lamp\n";
  if (perpendicular)  // the plane x = 0, facing +x, sharing the receiver's edge x = 0
    obj += "v 0 0 0\nv 0 1 0\nv 0 1 1\nv 0 0 1\nf 5 6 7 8\n";
  else  // the plane z = 1, facing -z
    obj += "v 0 0 1\nv 0 1 1\nv 1 1 1\nv 1 0 1\nf 5 6 7 8\n";
  if (occluder)  // [0.3, 0.7]^2 at z = 0.5, facing the receiver (either side occludes)
    obj += "usemtl block\nv 0.3 0.3 0.5\nv 0.3 0.7 0.5\nv 0.7 0.7 0.5\nv 0.7 0.3 0.5\nf 9 10 11 12\n";
  std::string mtl = "newmtl receiver\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0 0 0\nKe 1 2 3\nnewmtl block\nKd 0.5 0.5 0.5\n";
  return parse_obj("two_squares.obj", obj, {{"m.mtl", mtl}});
}

// Howell's catalogue of configuration factors, C-11: directly opposed parallel rectangles a x b
// at distance c; X = a / c, Y = b / c.
double parallel_rectangles(double X, double Y) {
  double x1 = std::sqrt(1 + X * X), y1 = std::sqrt(1 + Y * Y);
  return 2.0 / (std::numbers::pi * X * Y) *
         (std::log(std::sqrt((1 + X * X) * (1 + Y * Y) / (1 + X * X + Y * Y))) + X * y1 * std::atan(X / y1) +
          Y * x1 * std::atan(Y / x1) - X * std::atan(X) - Y * std::atan(Y));
}

// Howell C-14: perpendicular rectangles with a common edge of length l, from the one of width w
// to the one of height h; W = w / l, H = h / l.
double perpendicular_rectangles(double W, double H) {
  double w2 = W * W, h2 = H * H, s = std::sqrt(w2 + h2);
  double log_term = std::log((1 + w2) * (1 + h2) / (1 + w2 + h2) *
                             std::pow(w2 * (1 + w2 + h2) / ((1 + w2) * (w2 + h2)), w2) *
                             std::pow(h2 * (1 + h2 + w2) / ((1 + h2) * (h2 + w2)), h2));
  return (W * std::atan(1 / W) + H * std::atan(1 / H) - s * std::atan(1 / s) + 0.25 * log_term) / (std::numbers::pi * W);
}

// Howell B-3, by superposition: from a point (px, py, 0) facing +z to the parallel rectangle
// [x0, x1] x [y0, y1] at height c. G(A, B) is the corner case and odd in A and in B.
double point_to_parallel_rectangle(double px, double py, double x0, double x1, double y0, double y1, double c) {
  auto G = [](double A, double B) {
    double a1 = std::sqrt(1 + A * A), b1 = std::sqrt(1 + B * B);
    return (A / a1 * std::atan(B / a1) + B / b1 * std::atan(A / b1)) / (2 * std::numbers::pi);
  };
  if (x1 <= x0 || y1 <= y0) return 0.0;
  double a0 = (x0 - px) / c, a1 = (x1 - px) / c, b0 = (y0 - py) / c, b1 = (y1 - py) / c;
  return G(a1, b1) - G(a0, b1) - G(a1, b0) + G(a0, b0);
}

// The receiver's form factor to the lamp past the occluder, integrated by the midpoint rule on
// an N x N grid: from x the occluder [0.3, 0.7]^2 at z = 0.5 shadows [0.6, 1.4]^2 - x of the lamp
// plane z = 1 (central projection doubles distances from x); the visible part is the lamp minus
// that square (their intersection is a rectangle), each a closed form (B-3).
double occluded_factor(int N) {
  double sum = 0.0;
  for (int a = 0; a < N; ++a)
    for (int b = 0; b < N; ++b) {
      double px = (a + 0.5) / N, py = (b + 0.5) / N;
      double lamp = point_to_parallel_rectangle(px, py, 0, 1, 0, 1, 1);
      double shadow = point_to_parallel_rectangle(px, py, std::max(0.0, 0.6 - px), std::min(1.0, 1.4 - px),
                                                  std::max(0.0, 0.6 - py), std::min(1.0, 1.4 - py), 1);
      sum += lamp - shadow;
    }
  return sum / (static_cast<double>(N) * N);
}

// The receiver's sum_i A_i D_i = rho E A_r F_r->lamp. Each patch's direct estimate uses only its
// own samples, so the patches are independent and the sum's standard error is
// sqrt(sum_i A_i^2 se_i^2). Bound: 4 standard errors, plus 2e-6 relative for rounding (the
// geometry is exact in float; the solver works in double) and, for the occluded case, the
// quadrature's error (estimated as the change from N = 500 to N = 1000, times 2).
void check_receiver(const char* name, const Scene& scene, double factor, double extra) {
  PatchMesh mesh = mesh_scene(scene, {.target_patches = 600});
  ReferenceSolution s = solve_reference(mesh, {.rays_per_patch = 64, .light_samples = 256, .batches = 8, .seed = 5});
  for (int c = 0; c < 3; ++c) {
    double sum = 0.0, var = 0.0, area = 0.0;
    for (std::size_t j = 0; j < mesh.size(); ++j) {
      if (mesh.source_triangle[j] >= 2) continue;  // the receiver: the first quad
      sum += mesh.area[j] * s.direct[j][c];
      var += std::pow(mesh.area[j] * s.direct_se[j][c], 2);
      area += mesh.area[j];
    }
    double exact = 0.5 * (c + 1) * area * factor, se = std::sqrt(var);
    double bound = 4 * se + 2e-6 * exact + extra * 0.5 * (c + 1);
    std::printf("%s channel %d: reference %.7f, exact %.7f, difference %.2e, SE %.2e (relative %.2e), bound %.2e\n",
                name, c, sum, exact, sum - exact, se, se / exact, bound);
    EXPECT_NEAR(sum, exact, bound) << name << " channel " << c;
    EXPECT_NEAR(area, 1.0, 1e-6);
  }
}

TEST(ReferenceFormFactor, ParallelSquaresMatchClosedForm) {
  check_receiver("parallel", two_squares(false, false), parallel_rectangles(1, 1), 0.0);
}

TEST(ReferenceFormFactor, PerpendicularSquaresMatchClosedForm) {
  check_receiver("perpendicular", two_squares(true, false), perpendicular_rectangles(1, 1), 0.0);
}

// The occluder makes the control variate do real work: about a third of the lamp is hidden from
// the middle of the receiver, so most shadow rays there are blocked.
TEST(ReferenceFormFactor, OccludedSquaresMatchQuadrature) {
  double coarse = occluded_factor(500), fine = occluded_factor(1000);
  std::printf("occluded factor: %.8f (N = 500), %.8f (N = 1000); unoccluded %.8f\n", coarse, fine,
              parallel_rectangles(1, 1));
  ASSERT_LT(fine, 0.9 * parallel_rectangles(1, 1)) << "the occluder must hide a real part of the lamp";
  check_receiver("occluded", two_squares(false, true), fine, 2 * std::abs(fine - coarse));
}

// Standard-error calibration. Over S = 6 seeds, the sample variance v_i of patch i's estimate
// must match its reported squared standard error q_i = mean over seeds of se_i^2. We compare
// r = sum A v / sum A q (non-emitting patches, all channels). If the errors are calibrated,
// E[v_i] = E[q_i]; v_i has 5 degrees of freedom (relative sd sqrt(2/5) = 0.63) and q_i 6 * 7 = 42
// (0.22); patches are nearly independent (each has its own rays; the solve couples them weakly
// and the three channels are strongly correlated), so with ~400 patches the relative sd of r is
// about 0.67 / sqrt(400) ~ 0.035 (0.05 allowing for correlation): 0.8 < r < 1.25 is > 4 sd. A
// solver whose batches shared samples, or whose SE forgot the sqrt(R), fails by a factor >= 2.
TEST(ReferenceStandardError, MatchesSpreadOverSeeds) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 400});
  const int S = 6;
  std::vector<ReferenceSolution> runs;
  for (int s = 0; s < S; ++s)
    runs.push_back(solve_reference(mesh, {.rays_per_patch = 256, .light_samples = 32, .batches = 8,
                                          .seed = 100 + static_cast<uint64_t>(s)}));
  double v_sum = 0.0, q_sum = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    if (emits(mesh, j)) continue;
    for (int c = 0; c < 3; ++c) {
      double m = 0.0, v = 0.0, q = 0.0;
      for (const auto& r : runs) m += r.radiosity[j][c] / S;
      for (const auto& r : runs) {
        v += std::pow(r.radiosity[j][c] - m, 2) / (S - 1);
        q += std::pow(r.radiosity_se[j][c], 2) / S;
      }
      v_sum += mesh.area[j] * v;
      q_sum += mesh.area[j] * q;
    }
  }
  double ratio = v_sum / q_sum;
  std::printf("SE calibration: variance over seeds / reported SE^2 = %.3f (%d seeds, %zu patches)\n", ratio, S, mesh.size());
  EXPECT_GT(ratio, 0.8);
  EXPECT_LT(ratio, 1.25);
}

}  // namespace
}  // namespace sirad
