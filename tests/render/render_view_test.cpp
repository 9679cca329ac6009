// sirad tests: the patches drawn from a camera (render/image.h): corner radiosity (creases and
// material borders sharp, coplanar neighbours averaged), and render_view (orientation, culling,
// Gouraud and flat shading, no cracks, clipping, antialiasing, bad input refused).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <gtest/gtest.h>

#include "render/image.h"
#include "scene/camera.h"
#include "tests/mesh_builder.h"
#include "util/error.h"

namespace sirad {
namespace {

using test::facing_quad;
using test::inside_box;
using test::MeshBuilder;
using test::wall_value;

// The world point on the plane z = 0 seen through pixel (px, py) from a camera at (0, 0, d)
// looking at the origin, up +y.
glm::dvec2 plane_point(int px, int py, int width, int height, double d, double vfov_deg) {
  const double t = std::tan(vfov_deg * std::numbers::pi / 360.0);
  const double ndc_x = (px + 0.5) / width * 2.0 - 1.0, ndc_y = 1.0 - (py + 0.5) / height * 2.0;
  return {ndc_x * d * t * width / height, ndc_y * d * t};
}

void expect_near(const glm::vec3& actual, const glm::vec3& expected, float tolerance) {
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(actual[c], expected[c], tolerance) << "channel " << c;
}

// ---- corner_radiosity ----

// Two triangles hinged on the edge (0,0,0)-(0,1,0): A in the plane z = 0 (normal +z), B on the
// other side, folded by `degrees` (0 = coplanar). Both have area 0.5.
PatchMesh hinge(double degrees, uint32_t material_b) {
  const double r = degrees * std::numbers::pi / 180.0;
  MeshBuilder b;
  const uint32_t e0 = b.vertex({0, 0, 0}), e1 = b.vertex({0, 1, 0});
  const uint32_t a = b.vertex({-1, 0.5f, 0});
  const uint32_t c = b.vertex({float(std::cos(r)), 0.5f, float(std::sin(r))});
  b.patch(e0, e1, a);
  b.patch(e1, e0, c, material_b);
  return b.mesh;
}

TEST(OutputCorner, CoplanarNeighboursGetAreaWeightedMean) {
  // A = (v0 v1 v2), area 2; B = (v1 v3 v2), area 6; they share v1 and v2.
  MeshBuilder b;
  const uint32_t v0 = b.vertex({0, 0, 0}), v1 = b.vertex({2, 0, 0}), v2 = b.vertex({0, 2, 0}),
                 v3 = b.vertex({4, 4, 0});
  b.patch(v0, v1, v2);
  b.patch(v1, v3, v2);
  ASSERT_FLOAT_EQ(b.mesh.area[0], 2.0f);
  ASSERT_FLOAT_EQ(b.mesh.area[1], 6.0f);
  const glm::vec3 A(1, 2, 3), B(5, 6, 7), shared(4, 5, 6);  // (2 A + 6 B) / 8
  const auto corners = corner_radiosity(b.mesh, {A, B});
  ASSERT_EQ(corners.size(), 2u);
  expect_near(corners[0][0], A, 0);
  expect_near(corners[0][1], shared, 1e-6f);
  expect_near(corners[0][2], shared, 1e-6f);
  expect_near(corners[1][0], shared, 1e-6f);
  expect_near(corners[1][1], B, 0);
  expect_near(corners[1][2], shared, 1e-6f);
}

TEST(OutputCorner, CreasesAndMaterialBordersStaySharp) {
  const glm::vec3 A(1, 1, 1), B(3, 3, 3), mean(2, 2, 2);
  const struct {
    double degrees;
    uint32_t material_b;
    bool merged;
  } cases[] = {{0, 0, true}, {20, 0, true}, {40, 0, false}, {90, 0, false}, {0, 1, false}};
  for (const auto& c : cases) {
    SCOPED_TRACE(fmt::format("fold {} degrees, material {}", c.degrees, c.material_b));
    const auto corners = corner_radiosity(hinge(c.degrees, c.material_b), {A, B});
    // Corners 0 and 1 of both patches are the shared edge; corner 2 is each patch's own.
    expect_near(corners[0][0], c.merged ? mean : A, 1e-6f);
    expect_near(corners[0][1], c.merged ? mean : A, 1e-6f);
    expect_near(corners[1][0], c.merged ? mean : B, 1e-6f);
    expect_near(corners[1][1], c.merged ? mean : B, 1e-6f);
    expect_near(corners[0][2], A, 0);
    expect_near(corners[1][2], B, 0);
  }
}

TEST(OutputCorner, RejectsMismatchedRadiosity) {
  EXPECT_THROW(corner_radiosity(facing_quad(), {glm::vec3(1)}), Error);
}

// ---- render_view ----

TEST(OutputRender, FlatPatchAtCentreAndBackgroundAtCorners) {
  MeshBuilder b;
  b.patch(b.vertex({-1, -1, 0}), b.vertex({1, -1, 0}), b.vertex({0, 1, 0}));
  b.mesh.background = glm::vec3(0.25f, 0.5f, 0.75f);
  const Camera camera{{0, 0, 5}, {0, 0, 0}, {0, 1, 0}, 60.0f};
  for (Shading shading : {Shading::flat, Shading::gouraud}) {
    const Image image = render_view(b.mesh, {glm::vec3(1, 2, 3)}, camera, 63, 41, shading);
    ASSERT_EQ(image.width, 63);
    ASSERT_EQ(image.height, 41);
    ASSERT_EQ(image.pixels.size(), 63u * 41u);
    if (shading == Shading::flat)
      EXPECT_EQ(image.at(31, 20), glm::vec3(1, 2, 3));
    else
      expect_near(image.at(31, 20), glm::vec3(1, 2, 3), 1e-6f);
    for (auto [x, y] : {std::pair{0, 0}, {62, 0}, {0, 40}, {62, 40}})
      EXPECT_EQ(image.at(x, y), b.mesh.background) << x << "," << y;
  }
}

// Anti-aliasing: 4 x 4 samples per pixel are the mean of the 4x finer image's 4 x 4 block (the
// same framing: a pixel's samples tile its square), and along the triangle's slanted edges
// pixels take values strictly between the triangle's and the background's, where one sample
// per pixel gives only the two (jagged edges). Interior pixels keep the patch's value.
TEST(OutputRender, AntialiasingAveragesSamplesOverEachPixel) {
  MeshBuilder b;
  b.patch(b.vertex({-1, -1, 0}), b.vertex({1, -1, 0}), b.vertex({0, 1, 0}));
  b.mesh.background = glm::vec3(0.0f);
  const Camera camera{{0, 0, 5}, {0, 0, 0}, {0, 1, 0}, 60.0f};
  const Image fine = render_view(b.mesh, {glm::vec3(1)}, camera, 4 * 32, 4 * 24, Shading::flat);
  const Image aa = render_view_antialiased(b.mesh, {glm::vec3(1)}, camera, 32, 24, Shading::flat, 4);
  const Image one = render_view(b.mesh, {glm::vec3(1)}, camera, 32, 24, Shading::flat);
  int between = 0;
  for (int y = 0; y < 24; ++y)
    for (int x = 0; x < 32; ++x) {
      glm::vec3 sum(0.0f);
      for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) sum += fine.at(4 * x + i, 4 * y + j);
      expect_near(aa.at(x, y), sum / 16.0f, 1e-6f);
      between += aa.at(x, y).x > 0.0f && aa.at(x, y).x < 1.0f;
      EXPECT_TRUE(one.at(x, y).x == 0.0f || one.at(x, y).x == 1.0f);
    }
  EXPECT_GT(between, 20) << "edge pixels with partial coverage";
  EXPECT_EQ(aa.at(16, 12), glm::vec3(1.0f));
  EXPECT_THROW(render_view_antialiased(b.mesh, {glm::vec3(1)}, camera, 32, 24, Shading::flat, 0), Error);
}

TEST(OutputRender, BackFacesAreCulled) {
  MeshBuilder b;
  b.patch(b.vertex({-1, -1, 0}), b.vertex({1, -1, 0}), b.vertex({0, 1, 0}));
  const Camera behind{{0, 0, -5}, {0, 0, 0}, {0, 1, 0}, 60.0f};
  for (Shading shading : {Shading::flat, Shading::gouraud}) {
    const Image image = render_view(b.mesh, {glm::vec3(1, 2, 3)}, behind, 32, 32, shading);
    for (const glm::vec3& p : image.pixels) ASSERT_EQ(p, b.mesh.background);
  }
}

TEST(OutputRender, CornellOrientation) {
  // Red wall at x = 556 and green wall at x = 0 (facing inward), a blue patch high and a yellow
  // patch low on the back wall; the Cornell box camera.
  MeshBuilder b;
  b.quad({556, 0, 0}, {556, 0, 559}, {556, 548, 559}, {556, 548, 0});
  b.quad({0, 0, 0}, {0, 548, 0}, {0, 548, 559}, {0, 0, 559});
  b.quad({100, 400, 559}, {100, 548, 559}, {456, 548, 559}, {456, 400, 559});
  b.quad({100, 0, 559}, {100, 150, 559}, {456, 150, 559}, {456, 0, 559});
  const glm::vec3 red(1, 0, 0), green(0, 1, 0), blue(0, 0, 1), yellow(1, 1, 0);
  ASSERT_GT(b.mesh.normal[0].x * -1.0f, 0.99f);
  ASSERT_GT(b.mesh.normal[2].x, 0.99f);
  ASSERT_GT(b.mesh.normal[4].z * -1.0f, 0.99f);
  ASSERT_GT(b.mesh.normal[6].z * -1.0f, 0.99f);
  const std::vector<glm::vec3> radiosity{red, red, green, green, blue, blue, yellow, yellow};
  const Camera cornell{{278, 273, -800}, {278, 273, 0}, {0, 1, 0}, 39.3077f};
  const Image image = render_view(b.mesh, radiosity, cornell, 200, 150, Shading::flat);
  int counts[4] = {0, 0, 0, 0};
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const glm::vec3 p = image.at(x, y);
      if (p == red) {
        ++counts[0];
        EXPECT_LT(x, image.width / 2) << "red wall at " << x << "," << y;
      } else if (p == green) {
        ++counts[1];
        EXPECT_GE(x, image.width / 2) << "green wall at " << x << "," << y;
      } else if (p == blue) {
        ++counts[2];
        EXPECT_LT(y, image.height / 2) << "high patch at " << x << "," << y;
      } else if (p == yellow) {
        ++counts[3];
        EXPECT_GE(y, image.height / 2) << "low patch at " << x << "," << y;
      } else {
        EXPECT_EQ(p, b.mesh.background) << x << "," << y;
      }
    }
  for (int count : counts) EXPECT_GT(count, 100);
}

TEST(OutputRender, GouraudGradientAndFlatStep) {
  // The quad's patches carry 1 (below the diagonal y = x) and 3 (above). Corner means: 2 on the
  // diagonal's ends, 1 and 3 at the other corners, so Gouraud is the plane 2 - x/2 + y/2.
  const PatchMesh quad = facing_quad();
  const std::vector<glm::vec3> radiosity{glm::vec3(1), glm::vec3(3)};
  const Camera camera{{0, 0, 5}, {0, 0, 0}, {0, 1, 0}, 50.0f};
  const int size = 127;
  const Image gouraud = render_view(quad, radiosity, camera, size, size, Shading::gouraud);
  const Image flat = render_view(quad, radiosity, camera, size, size, Shading::flat);
  int inside = 0;
  float lowest = 10, highest = -10;
  for (int py = 0; py < size; ++py)
    for (int px = 0; px < size; ++px) {
      const glm::dvec2 q = plane_point(px, py, size, size, 5.0, 50.0);
      const bool in_quad = std::abs(q.x) < 0.99 && std::abs(q.y) < 0.99;
      const bool off_quad = std::abs(q.x) > 1.01 || std::abs(q.y) > 1.01;
      if (off_quad) {
        EXPECT_EQ(gouraud.at(px, py), quad.background);
        EXPECT_EQ(flat.at(px, py), quad.background);
      }
      if (!in_quad) continue;
      ++inside;
      const float expected = float(2.0 - q.x / 2 + q.y / 2);
      expect_near(gouraud.at(px, py), glm::vec3(expected), 1e-4f);
      lowest = std::min(lowest, gouraud.at(px, py).x);
      highest = std::max(highest, gouraud.at(px, py).x);
      if (std::abs(q.x - q.y) > 1e-3) {
        EXPECT_EQ(flat.at(px, py), glm::vec3(q.y < q.x ? 1.0f : 3.0f));
      }
    }
  EXPECT_GT(inside, 1000);
  EXPECT_LT(lowest, 1.1f);
  EXPECT_GT(highest, 2.9f);
}

TEST(OutputRender, GouraudIsPerspectiveCorrect) {
  // The Gouraud quad laid on the floor y = -1 (local (u, v) in [-1, 1]^2 at world
  // (4u, -1, -12 - 8v)) and seen at a grazing angle: each pixel must show 2 - u/2 + v/2 at the
  // point its ray hits, which screen-space (affine) interpolation would miss.
  const auto world = [](double u, double v) { return glm::vec3(4 * u, -1, -12 - 8 * v); };
  MeshBuilder b;
  b.quad(world(-1, -1), world(1, -1), world(1, 1), world(-1, 1));
  ASSERT_GT(b.mesh.normal[0].y, 0.99f);
  const std::vector<glm::vec3> radiosity{glm::vec3(1), glm::vec3(3)};
  const Camera camera{{0, 0, 0}, {0, -1, -12}, {0, 1, 0}, 60.0f};
  const int width = 160, height = 120;
  const Image image = render_view(b.mesh, radiosity, camera, width, height, Shading::gouraud);

  const glm::dvec3 forward = glm::normalize(glm::dvec3(camera.look_at - camera.eye));
  const glm::dvec3 right = glm::normalize(glm::cross(forward, glm::dvec3(camera.up)));
  const glm::dvec3 up = glm::cross(right, forward);
  const double t = std::tan(30.0 * std::numbers::pi / 180.0);
  int checked = 0;
  for (int py = 0; py < height; ++py)
    for (int px = 0; px < width; ++px) {
      const glm::dvec3 d = forward + right * (((px + 0.5) / width * 2 - 1) * t * width / height) +
                           up * ((1 - (py + 0.5) / height * 2) * t);
      if (d.y >= 0) continue;
      const glm::dvec3 hit = d * (-1.0 / d.y);
      const double u = hit.x / 4, v = (-12 - hit.z) / 8;
      if (std::abs(u) > 0.98 || std::abs(v) > 0.98) continue;
      ++checked;
      expect_near(image.at(px, py), glm::vec3(float(2 - u / 2 + v / 2)), 1e-4f);
    }
  EXPECT_GT(checked, 1000);
}

TEST(OutputRender, NoCracksOnSharedEdgesThroughPixelCentres) {
  // A square of two patches facing the camera, its shared diagonal through pixel centres; over
  // many sizes and fields of view, every diagonal pixel inside the square must be covered
  // (edge functions evaluated in one order per edge; else rounding opens gaps).
  std::mt19937 rng(7);
  const auto uniform = [&] { return double(rng()) / 4294967296.0; };
  int checked = 0;
  for (int trial = 0; trial < 600; ++trial) {
    const float s = float(0.5 + 3 * uniform());
    const bool anti = trial % 2 == 1;
    PatchMesh m;
    m.materials = {Material{"white", glm::vec3(0.5f), glm::vec3(0.0f)}};
    m.vertices = {{-s, -s, 0}, {s, -s, 0}, {s, s, 0}, {-s, s, 0}};
    m.patches = anti ? std::vector<std::array<uint32_t, 3>>{{0, 1, 3}, {1, 2, 3}}
                     : std::vector<std::array<uint32_t, 3>>{{0, 1, 2}, {0, 2, 3}};
    m.normal = {{0, 0, 1}, {0, 0, 1}};
    m.area = {2 * s * s, 2 * s * s};
    m.material = {0, 0};
    m.background = glm::vec3(-1);
    const double d = 1 + 20 * uniform(), fov = 10 + 100 * uniform();
    const int size = 16 + int(300 * uniform());
    const Camera camera{{0, 0, float(d)}, {0, 0, 0}, {0, 1, 0}, float(fov)};
    const Image image =
        render_view(m, {glm::vec3(1), glm::vec3(1)}, camera, size, size, Shading::flat);
    for (int i = 0; i < size; ++i) {
      const glm::dvec2 q = plane_point(i, i, size, size, d, fov);
      if (std::abs(q.x) > 0.99 * s) continue;
      ++checked;
      const int y = anti ? i : size - 1 - i;
      ASSERT_EQ(image.at(i, y), glm::vec3(1)) << "trial " << trial << " pixel " << i << "," << y;
    }
  }
  EXPECT_GT(checked, 10000);
}

TEST(OutputRender, NearerPatchWins) {
  // A small quad at z = 1 in front of a large one at z = 0, in both patch orders.
  const Camera camera{{0, 0, 5}, {0, 0, 0}, {0, 1, 0}, 60.0f};
  for (bool near_first : {false, true}) {
    MeshBuilder b;
    const auto add_far = [&] { b.quad({-2, -2, 0}, {2, -2, 0}, {2, 2, 0}, {-2, 2, 0}, 0); };
    const auto add_near = [&] { b.quad({-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}, 1); };
    std::vector<glm::vec3> radiosity;
    if (near_first) {
      add_near();
      add_far();
      radiosity = {glm::vec3(2), glm::vec3(2), glm::vec3(1), glm::vec3(1)};
    } else {
      add_far();
      add_near();
      radiosity = {glm::vec3(1), glm::vec3(1), glm::vec3(2), glm::vec3(2)};
    }
    for (Shading shading : {Shading::flat, Shading::gouraud}) {
      SCOPED_TRACE(
          fmt::format("near first {}, gouraud {}", near_first, shading == Shading::gouraud));
      const Image image = render_view(b.mesh, radiosity, camera, 65, 65, shading);
      expect_near(image.at(32, 32), glm::vec3(2), 1e-6f);  // near quad
      expect_near(image.at(32, 12), glm::vec3(1), 1e-6f);  // far quad, above the near one
    }
  }
}

TEST(OutputRender, PatchPartlyBehindCameraIsClipped) {
  // A floor y = -1 spanning z in [-100, 100] around a camera at the origin looking down -z: its
  // patches reach behind the camera. Expected per pixel from the ray's hit with the floor.
  MeshBuilder b;
  b.quad({-100, -1, -100}, {-100, -1, 100}, {100, -1, 100}, {100, -1, -100});
  ASSERT_GT(b.mesh.normal[0].y, 0.99f);
  b.mesh.background = glm::vec3(-1);
  const std::vector<glm::vec3> radiosity{glm::vec3(0.5f), glm::vec3(0.5f)};
  const Camera camera{{0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 90.0f};
  const int width = 96, height = 64;
  for (Shading shading : {Shading::flat, Shading::gouraud}) {
    const Image image = render_view(b.mesh, radiosity, camera, width, height, shading);
    int floor_pixels = 0;
    for (int py = 0; py < height; ++py)
      for (int px = 0; px < width; ++px) {
        const double ndc_x = ((px + 0.5) / width * 2 - 1) * width / height;
        const double ndc_y = 1 - (py + 0.5) / height * 2;
        const double t = ndc_y < 0 ? -1.0 / ndc_y : 1e300;  // ray (ndc_x, ndc_y, -1) hits y = -1
        const double reach = std::max(t, std::abs(ndc_x * t));
        if (reach < 99.0) {
          ++floor_pixels;
          expect_near(image.at(px, py), glm::vec3(0.5f), 1e-6f);
        } else if (reach > 101.0) {
          EXPECT_EQ(image.at(px, py), b.mesh.background) << px << "," << py;
        }
      }
    EXPECT_GT(floor_pixels, width * height / 3);
  }
}

// Every pixel of a closed box seen from inside shows the wall its ray hits: no cracks between
// patches, correct near clipping for the walls beside and behind the camera, creases kept.
void check_inside_box(int n, int width, int height) {
  const auto [mesh, radiosity] = inside_box(n);
  PatchMesh box = mesh;
  box.background = glm::vec3(-1);
  const Camera camera{{0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 100.0f};
  const double t = std::tan(50.0 * std::numbers::pi / 180.0);
  for (Shading shading : {Shading::flat, Shading::gouraud}) {
    const Image image = render_view(box, radiosity, camera, width, height, shading);
    int mismatches = 0;
    for (int py = 0; py < height; ++py)
      for (int px = 0; px < width; ++px) {
        const glm::dvec3 d{((px + 0.5) / width * 2 - 1) * t * width / height,
                           (1 - (py + 0.5) / height * 2) * t, -1.0};
        const glm::dvec3 a = glm::abs(d);
        const int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
        const double second = axis == 0   ? std::max(a.y, a.z)
                              : axis == 1 ? std::max(a.x, a.z)
                                          : std::max(a.x, a.y);
        if (a[axis] - second < 1e-2 * a[axis]) continue;  // near a cube edge
        const glm::vec3 expected = wall_value(2 * axis + (d[axis] > 0 ? 1 : 0));
        const glm::vec3 p = image.at(px, py);
        if (glm::length(p - expected) > 1e-5f) ++mismatches;
        if (p == box.background) ADD_FAILURE() << "crack at " << px << "," << py;
      }
    EXPECT_EQ(mismatches, 0);
  }
}

TEST(OutputRender, InsideBoxEveryPixelShowsItsWall) { check_inside_box(4, 96, 64); }

TEST(OutputRender, InsideBoxLargeMesh) {
  // About 100k patches at 512 x 512 (the timing is printed, not asserted).
  const auto start = std::chrono::steady_clock::now();
  check_inside_box(91, 512, 512);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("99372 patches, 2 views at 512x512 with checks: %.3f s\n", seconds);
}

TEST(OutputRender, RejectsBadInput) {
  const PatchMesh quad = facing_quad();
  const std::vector<glm::vec3> radiosity{glm::vec3(1), glm::vec3(3)};
  const Camera camera{{0, 0, 5}, {0, 0, 0}, {0, 1, 0}, 50.0f};
  EXPECT_THROW(render_view(quad, {glm::vec3(1)}, camera, 8, 8, Shading::flat), Error);
  EXPECT_THROW(render_view(quad, radiosity, camera, 0, 8, Shading::flat), Error);
  EXPECT_THROW(
      render_view(quad, radiosity, {{0, 0, 5}, {0, 0, 5}, {0, 1, 0}, 50.0f}, 8, 8, Shading::flat),
      Error);
  EXPECT_THROW(
      render_view(quad, radiosity, {{0, 0, 5}, {0, 0, 0}, {0, 0, 1}, 50.0f}, 8, 8, Shading::flat),
      Error);
  EXPECT_THROW(
      render_view(quad, radiosity, {{0, 0, 5}, {0, 0, 0}, {0, 1, 0}, 180.0f}, 8, 8, Shading::flat),
      Error);
}

}  // namespace
}  // namespace sirad
