// sirad tests: the outputs (corner radiosity, camera view, EXR, PNG, PLY, atomic writes).
#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfDoubleAttribute.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfIntAttribute.h>
#include <OpenEXR/ImfStringAttribute.h>
#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <gtest/gtest.h>
#include <png.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include "io/results.h"
#include "io/write.h"
#include "tests/png_util.h"
#include "util/error.h"

namespace sirad {
namespace {

namespace fs = std::filesystem;

// ---- helpers ----

// Builds a PatchMesh by hand: normal and area from each patch's CCW winding.
struct MeshBuilder {
  PatchMesh mesh;

  MeshBuilder() {
    mesh.materials = {Material{"white", glm::vec3(0.5f, 0.6f, 0.7f), glm::vec3(0.0f)},
                      Material{"light", glm::vec3(0.25f), glm::vec3(10.0f, 20.0f, 30.0f)}};
    mesh.hash = "0123456789abcdef0123456789abcdef";
  }
  uint32_t vertex(glm::vec3 p) {
    mesh.vertices.push_back(p);
    return static_cast<uint32_t>(mesh.vertices.size() - 1);
  }
  void patch(uint32_t a, uint32_t b, uint32_t c, uint32_t material = 0) {
    const glm::vec3 n =
        glm::cross(mesh.vertices[b] - mesh.vertices[a], mesh.vertices[c] - mesh.vertices[a]);
    mesh.patches.push_back({a, b, c});
    mesh.normal.push_back(glm::normalize(n));
    mesh.area.push_back(0.5f * glm::length(n));
    mesh.material.push_back(material);
    mesh.source_triangle.push_back(static_cast<uint32_t>(mesh.size() - 1));
  }
  // Two patches (a, b, c) and (a, c, d) of the quad a b c d.
  void quad(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, uint32_t material = 0) {
    const uint32_t ia = vertex(a), ib = vertex(b), ic = vertex(c), id = vertex(d);
    patch(ia, ib, ic, material);
    patch(ia, ic, id, material);
  }
};

// The unit-ish quad [-1, 1]^2 at z = 0 facing +z: patch 0 = (v0 v1 v2) below the diagonal
// y = x, patch 1 = (v0 v2 v3) above it.
PatchMesh facing_quad() {
  MeshBuilder b;
  b.quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0});
  return b.mesh;
}

// The cube [-1, 1]^3 seen from inside (inward normals), each face n x n quads with welded
// vertices; face f has radiosity wall_value(f). Faces: -x +x -y +y -z +z.
glm::vec3 wall_value(int face) {
  static const std::array<glm::vec3, 6> values{glm::vec3(1, 0, 0), glm::vec3(0, 1, 0),
                                               glm::vec3(0, 0, 1), glm::vec3(1, 1, 0),
                                               glm::vec3(0, 1, 1), glm::vec3(1, 0, 1)};
  return values[face];
}

std::pair<PatchMesh, std::vector<glm::vec3>> inside_box(int n) {
  const glm::vec3 x(2, 0, 0), y(0, 2, 0), z(0, 0, 2);
  struct Face {
    glm::vec3 origin, u, v;
  };
  const std::array<Face, 6> faces{Face{{-1, -1, -1}, y, z}, Face{{1, -1, -1}, z, y},
                                  Face{{-1, -1, -1}, z, x}, Face{{-1, 1, -1}, x, z},
                                  Face{{-1, -1, -1}, x, y}, Face{{-1, -1, 1}, y, x}};
  MeshBuilder b;
  std::vector<glm::vec3> radiosity;
  for (int f = 0; f < 6; ++f) {
    const Face& face = faces[f];
    const auto first = static_cast<uint32_t>(b.mesh.vertices.size());
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i)
        b.vertex(face.origin + face.u * (float(i) / n) + face.v * (float(j) / n));
    const auto at = [&](int i, int j) { return first + static_cast<uint32_t>(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        b.patch(at(i, j), at(i + 1, j), at(i + 1, j + 1));
        b.patch(at(i, j), at(i + 1, j + 1), at(i, j + 1));
        radiosity.insert(radiosity.end(), 2, wall_value(f));
      }
  }
  return {b.mesh, radiosity};
}

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

std::vector<unsigned char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

bool tool_available(const char* tool) {
  return std::system(fmt::format("command -v {} >/dev/null 2>&1", tool).c_str()) == 0;
}

// A fresh directory per test, removed afterwards.
class OutputFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / fmt::format("sirad_output_test_{}_{}_{}", ::getpid(),
                                                   info->test_suite_name(), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string file(const std::string& name) const { return (dir_ / name).string(); }
  std::vector<std::string> listing() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir_))
      names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

  fs::path dir_;
};

class OutputExr : public OutputFiles {};
class OutputPng : public OutputFiles {};
class OutputPly : public OutputFiles {};
class OutputAtomic : public OutputFiles {};

Image small_image() {
  Image image{5, 3, {}};
  for (int i = 0; i < 15; ++i)
    image.pixels.push_back(glm::vec3(0.1f * i, -2.5f + i, 1e-30f * float(i + 1)));
  image.pixels[7] = glm::vec3(65504.5f, 1e30f, std::numeric_limits<float>::denorm_min());
  return image;
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

// ---- EXR ----

TEST_F(OutputExr, RoundTrip) {
  const Image image = small_image();
  const Attributes attributes{{"sirad.bundles", int64_t{1024}},
                              {"sirad.min_int", int64_t{std::numeric_limits<int32_t>::min()}},
                              {"sirad.big", int64_t{1} << 40},
                              {"sirad.seconds", 1.25},
                              {"sirad.scene", std::string("cornell box")}};
  const std::string path = file("view.exr");
  write_exr(path, image, attributes);
  EXPECT_EQ(listing(), std::vector<std::string>{"view.exr"});

  Imf::InputFile in(path.c_str());
  const Imf::Header& header = in.header();
  EXPECT_EQ(header.compression(), Imf::ZIP_COMPRESSION);
  EXPECT_EQ(header.dataWindow().min.x, 0);
  EXPECT_EQ(header.dataWindow().max.x, image.width - 1);
  EXPECT_EQ(header.dataWindow().max.y, image.height - 1);
  int channel_count = 0;
  for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
    ++channel_count;
    EXPECT_EQ(it.channel().type, Imf::FLOAT) << it.name();
  }
  EXPECT_EQ(channel_count, 3);
  for (const char* channel : {"R", "G", "B"})
    EXPECT_NE(header.channels().findChannel(channel), nullptr);

  const auto* bundles = header.findTypedAttribute<Imf::IntAttribute>("sirad.bundles");
  ASSERT_NE(bundles, nullptr);
  EXPECT_EQ(bundles->value(), 1024);
  const auto* min_int = header.findTypedAttribute<Imf::IntAttribute>("sirad.min_int");
  ASSERT_NE(min_int, nullptr);
  EXPECT_EQ(min_int->value(), std::numeric_limits<int32_t>::min());
  const auto* big = header.findTypedAttribute<Imf::DoubleAttribute>("sirad.big");
  ASSERT_NE(big, nullptr);
  EXPECT_EQ(big->value(), 1099511627776.0);
  const auto* seconds = header.findTypedAttribute<Imf::DoubleAttribute>("sirad.seconds");
  ASSERT_NE(seconds, nullptr);
  EXPECT_EQ(seconds->value(), 1.25);
  const auto* scene = header.findTypedAttribute<Imf::StringAttribute>("sirad.scene");
  ASSERT_NE(scene, nullptr);
  EXPECT_EQ(scene->value(), "cornell box");

  std::vector<glm::vec3> pixels(image.pixels.size(), glm::vec3(-7));
  char* base = reinterpret_cast<char*>(pixels.data());
  const std::size_t xs = sizeof(glm::vec3), ys = xs * image.width;
  Imf::FrameBuffer frame;
  frame.insert("R", Imf::Slice(Imf::FLOAT, base, xs, ys));
  frame.insert("G", Imf::Slice(Imf::FLOAT, base + 4, xs, ys));
  frame.insert("B", Imf::Slice(Imf::FLOAT, base + 8, xs, ys));
  in.setFrameBuffer(frame);
  in.readPixels(0, image.height - 1);
  EXPECT_EQ(std::memcmp(pixels.data(), image.pixels.data(), pixels.size() * sizeof(glm::vec3)), 0);

  if (tool_available("exrinfo")) {
    // Its output, not its exit status: Debian's exrinfo 3.1 returns a random status on about
    // one run in six for any file.
    EXPECT_EQ(std::system(fmt::format("exrinfo -s '{}' 2>&1 | grep -q \"channels: 3 channels\"", path).c_str()), 0);
  }
  if (tool_available("exrheader")) {
    EXPECT_EQ(std::system(fmt::format("exrheader '{}' >/dev/null", path).c_str()), 0);
  }
}

TEST_F(OutputExr, RejectsBadImagesAndAttributes) {
  const Image image = small_image();
  const std::string path = file("bad.exr");
  EXPECT_THROW(write_exr(path, Image{}, {}), Error);
  Image short_image = image;
  short_image.pixels.pop_back();
  EXPECT_THROW(write_exr(path, short_image, {}), Error);
  for (const char* name : {"", "compression", "channels", "dataWindow", "owner"})
    EXPECT_THROW(write_exr(path, image, {{name, int64_t{1}}}), Error) << "'" << name << "'";
  EXPECT_THROW(write_exr(path, image, {{std::string(300, 'a'), 1.0}}), Error);
  EXPECT_THROW(write_exr(path, image, {{"sirad.x", 1.0}, {"sirad.x", std::string("y")}}), Error);
  EXPECT_TRUE(listing().empty());
}

// ---- PNG ----

// Reads an 8-bit RGB PNG (it must be one: what write_png writes).
std::vector<unsigned char> read_png(const std::string& path, int& width, int& height) {
  png_uint_32 format = 0;
  std::vector<unsigned char> bytes = sirad::test::read_png(path, width, height, &format);
  EXPECT_EQ(format, static_cast<png_uint_32>(PNG_FORMAT_RGB));
  return bytes;
}

TEST_F(OutputPng, ToneMapAndExposure) {
  const float inf = std::numeric_limits<float>::infinity(),
              nan = std::numeric_limits<float>::quiet_NaN();
  Image image{3,
              2,
              {glm::vec3(0, 1, 0.5f), glm::vec3(nan, inf, -inf), glm::vec3(2, -1, 0.25f),
               glm::vec3(0.001f, 0.5f, 0), glm::vec3(1, 1, 1), glm::vec3(0.25f, 0.5f, 0.125f)}};
  int width = 0, height = 0;
  write_png(file("a.png"), image);
  EXPECT_EQ(read_png(file("a.png"), width, height),
            (std::vector<unsigned char>{0, 255, 188, 0, 255, 0, 255, 0, 137, 3, 188, 0, 255, 255,
                                        255, 137, 188, 99}));
  EXPECT_EQ(width, 3);
  EXPECT_EQ(height, 2);
  write_png(file("b.png"), image, 1.0f);
  EXPECT_EQ(read_png(file("b.png"), width, height),
            (std::vector<unsigned char>{0, 255, 255, 0, 255, 0, 255, 0, 188, 7, 255, 0, 255, 255,
                                        255, 188, 255, 137}));
  EXPECT_EQ(listing(), (std::vector<std::string>{"a.png", "b.png"}));
}

TEST_F(OutputPng, LibpngErrorBecomesSiradError) {
  // Wider than libpng's default limit of 1,000,000 columns: libpng fails in png_set_IHDR.
  Image image{1000001, 1, std::vector<glm::vec3>(1000001, glm::vec3(0.5f))};
  const std::string path = file("wide.png");
  try {
    write_png(path, image);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
  }
  EXPECT_THROW(write_png(path, Image{}), Error);
  EXPECT_THROW(write_png(path, small_image(), std::numeric_limits<float>::quiet_NaN()), Error);
  EXPECT_TRUE(listing().empty());
}

// ---- PLY ----

template <typename T>
T get_le(const std::vector<unsigned char>& bytes, std::size_t& at) {
  uint32_t bits = 0;
  for (int i = 0; i < 4; ++i) bits |= uint32_t(bytes.at(at + i)) << (8 * i);
  at += 4;
  return std::bit_cast<T>(bits);
}

TEST_F(OutputPly, HeaderAndBody) {
  MeshBuilder b;
  b.quad({0, 0, 0}, {1.5f, 0, 0}, {1.5f, 2.25f, 0}, {0, 2.25f, -0.125f});
  b.mesh.material[1] = 1;
  const std::vector<glm::vec3> radiosity{glm::vec3(0.1f, 0.2f, 0.3f), glm::vec3(40, 50, 60)};
  const std::string path = file("mesh.ply");
  write_ply(path, b.mesh, radiosity);
  const std::vector<unsigned char> bytes = read_bytes(path);

  const std::string expected_header =
      "ply\n"
      "format binary_little_endian 1.0\n"
      "comment sirad scene hash 0123456789abcdef0123456789abcdef\n"
      "comment sirad background 0 0 0\n"
      "element vertex 6\n"
      "property float x\n"
      "property float y\n"
      "property float z\n"
      "property uchar red\n"
      "property uchar green\n"
      "property uchar blue\n"
      "element face 2\n"
      "property list uchar int vertex_indices\n"
      "property float radiosity_r\n"
      "property float radiosity_g\n"
      "property float radiosity_b\n"
      "property float reflectance_r\n"
      "property float reflectance_g\n"
      "property float reflectance_b\n"
      "property float emission_r\n"
      "property float emission_g\n"
      "property float emission_b\n"
      "end_header\n";
  ASSERT_GE(bytes.size(), expected_header.size());
  EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + expected_header.size()), expected_header);
  // The two patches have different materials: their corners are not shared (6 vertices, not
  // the 4 welded ones), each vertex has its patch's value as the PNG's sRGB bytes.
  ASSERT_EQ(bytes.size(), expected_header.size() + 6 * 15 + 2 * (1 + 12 + 36));
  auto srgb_byte = [](float v) {
    double x = std::clamp(static_cast<double>(v), 0.0, 1.0);
    return static_cast<int>(std::lround(255.0 * (x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055)));
  };
  std::size_t at = expected_header.size();
  for (std::size_t j = 0; j < 2; ++j)
    for (int k = 0; k < 3; ++k) {
      for (int c = 0; c < 3; ++c) EXPECT_EQ(get_le<float>(bytes, at), b.mesh.vertices[b.mesh.patches[j][k]][c]);
      for (int c = 0; c < 3; ++c) EXPECT_EQ(int(bytes.at(at++)), srgb_byte(radiosity[j][c])) << j << " " << k << " " << c;
    }
  for (std::size_t j = 0; j < 2; ++j) {
    EXPECT_EQ(bytes.at(at++), 3);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(get_le<int32_t>(bytes, at), int32_t(3 * j + k));
    for (const glm::vec3& v : {radiosity[j], b.mesh.reflectance(j), b.mesh.emission(j)})
      for (int c = 0; c < 3; ++c) EXPECT_EQ(get_le<float>(bytes, at), v[c]);
  }
  EXPECT_EQ(at, bytes.size());
}

TEST_F(OutputPly, RejectsMismatchedRadiosity) {
  EXPECT_THROW(write_ply(file("mesh.ply"), facing_quad(), {glm::vec3(1)}), Error);
  EXPECT_TRUE(listing().empty());
}

// ---- atomic writes ----

TEST_F(OutputAtomic, MissingDirectoryThrowsAndLeavesNothing) {
  const Image image = small_image();
  const PatchMesh quad = facing_quad();
  const std::vector<glm::vec3> radiosity{glm::vec3(1), glm::vec3(3)};
  const std::string exr = file("missing/x.exr"), png = file("missing/x.png"),
                    ply = file("missing/x.ply");
  for (const auto& [path, write] :
       {std::pair<std::string, std::function<void()>>{exr, [&] { write_exr(exr, image, {}); }},
        {png, [&] { write_png(png, image); }},
        {ply, [&] { write_ply(ply, quad, radiosity); }}}) {
    try {
      write();
      ADD_FAILURE() << "no error for " << path;
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()),
                fmt::format("cannot write {}: No such file or directory", path));
    }
  }
  EXPECT_TRUE(listing().empty());
}

TEST_F(OutputAtomic, ReplacesExistingFiles) {
  const Image image = small_image();
  const PatchMesh quad = facing_quad();
  for (const char* name : {"x.exr", "x.png", "x.ply"}) std::ofstream(file(name)) << "old contents";
  write_exr(file("x.exr"), image, {});
  write_png(file("x.png"), image);
  write_ply(file("x.ply"), quad, {glm::vec3(1), glm::vec3(3)});
  EXPECT_EQ(listing(), (std::vector<std::string>{"x.exr", "x.ply", "x.png"}));
  const auto exr = read_bytes(file("x.exr"));
  ASSERT_GE(exr.size(), 4u);
  EXPECT_EQ(std::vector<unsigned char>(exr.begin(), exr.begin() + 4),
            (std::vector<unsigned char>{0x76, 0x2f, 0x31, 0x01}));
  int width = 0, height = 0;
  EXPECT_EQ(read_png(file("x.png"), width, height).size(), image.pixels.size() * 3);
  const auto ply = read_bytes(file("x.ply"));
  EXPECT_EQ(std::string(ply.begin(), ply.begin() + 4), "ply\n");
}

// Limits the size of files this process may write (RLIMIT_FSIZE, with SIGXFSZ ignored so a write
// past it fails with EFBIG) while in scope.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    getrlimit(RLIMIT_FSIZE, &saved_);
    saved_handler_ = signal(SIGXFSZ, SIG_IGN);
    rlimit limit = saved_;
    limit.rlim_cur = bytes;
    setrlimit(RLIMIT_FSIZE, &limit);
  }
  ~FileSizeLimit() {
    setrlimit(RLIMIT_FSIZE, &saved_);
    signal(SIGXFSZ, saved_handler_);
  }

 private:
  rlimit saved_{};
  sighandler_t saved_handler_;
};

TEST_F(OutputAtomic, WriteFailureThrowsAndLeavesNothing) {
  // Incompressible content, far larger than the limit: the writes fail part way.
  std::mt19937 rng(3);
  Image noise{200, 200, {}};
  for (int i = 0; i < 200 * 200; ++i)
    noise.pixels.push_back(glm::vec3(float(rng()) / 4294967296.0f, float(rng()) / 4294967296.0f,
                                     float(rng()) / 4294967296.0f));
  const auto [box, radiosity] = inside_box(20);
  const std::string exr = file("x.exr"), png = file("x.png"), ply = file("x.ply");
  {
    const FileSizeLimit limit(10000);
    for (const auto& [path, write] :
         {std::pair<std::string, std::function<void()>>{exr, [&] { write_exr(exr, noise, {}); }},
          {png, [&] { write_png(png, noise); }},
          {ply, [&] { write_ply(ply, box, radiosity); }}}) {
      try {
        write();
        ADD_FAILURE() << "no error for " << path;
      } catch (const Error& e) {
        EXPECT_EQ(std::string(e.what()), fmt::format("cannot write {}: File too large", path));
      }
    }
  }
  {
    // A small EXR stays in the stdio buffer until OpenEXR seeks back to write its line offsets
    // (in OutputFile's destructor, which swallows errors): the failure must still surface.
    const FileSizeLimit limit(300);
    try {
      write_exr(exr, small_image(), {});
      ADD_FAILURE() << "no error for the small EXR";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()), fmt::format("cannot write {}: File too large", exr));
    }
  }
  EXPECT_TRUE(listing().empty());
}

TEST_F(OutputAtomic, FailedRenameRemovesTemporary) {
  // The target is a directory: the temporary is complete but cannot be renamed onto it.
  fs::create_directory(file("target"));
  const Image image = small_image();
  EXPECT_THROW(write_exr(file("target"), image, {}), Error);
  EXPECT_THROW(write_png(file("target"), image), Error);
  EXPECT_THROW(write_ply(file("target"), facing_quad(), {glm::vec3(1), glm::vec3(3)}), Error);
  EXPECT_EQ(listing(), std::vector<std::string>{"target"});
  EXPECT_TRUE(fs::is_empty(file("target")));
}

}  // namespace
}  // namespace sirad

namespace sirad {
namespace {

class OutputResults : public OutputFiles {
 protected:
  PatchMesh quad_with_camera() const {
    PatchMesh m = facing_quad();
    m.camera = Camera{glm::vec3(0, 0, 3), glm::vec3(0), glm::vec3(0, 1, 0), 60.0f};
    return m;
  }
  ResultOptions small() const {
    ResultOptions o;
    o.width = 8;
    o.height = 8;
    return o;
  }
};

// The four outputs are all replaced or none is: with a directory where the PLY goes, the old
// EXR, PNG and glTF stay as they were, and no temporary is left.
TEST_F(OutputResults, AllOrNone) {
  for (const char* name : {"x.exr", "x.png", "x.glb"}) std::ofstream(file(name)) << "old contents";
  fs::create_directory(file("x.ply"));
  EXPECT_THROW(write_results(file("x"), quad_with_camera(), {glm::vec3(1), glm::vec3(3)}, small(), {}), Error);
  EXPECT_EQ(listing(), (std::vector<std::string>{"x.exr", "x.glb", "x.ply", "x.png"}));
  for (const char* name : {"x.exr", "x.png", "x.glb"}) {
    std::ifstream in(file(name));
    std::string text((std::istreambuf_iterator<char>(in)), {});
    EXPECT_EQ(text, "old contents") << name;
  }
  fs::remove(file("x.ply"));
  write_results(file("x"), quad_with_camera(), {glm::vec3(1), glm::vec3(3)}, small(), {});
  EXPECT_EQ(listing(), (std::vector<std::string>{"x.exr", "x.glb", "x.ply", "x.png"}));
}

// A result with a non-finite value is never written (it used to give an all-NaN PLY and exit 0).
TEST_F(OutputResults, NonFiniteResultIsNeverWritten) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  try {
    write_results(file("x"), quad_with_camera(), {glm::vec3(1), glm::vec3(1, nan, 1)}, small(), {});
    ADD_FAILURE() << "written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not finite at patch 1"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(listing().empty());
}

// A solution outlives its image (issue 35): where the final gather cannot render the view (a
// camera 1e20 away, past check_camera_reach), the PLY and glb are still written and the error
// says so; no EXR or PNG is. The same where the image failed before (a cluster run's
// RunResult::image_error): nothing is rendered.
TEST_F(OutputResults, TheSolutionIsKeptWhenItsImageFails) {
  PatchMesh far = quad_with_camera();
  far.camera->eye = glm::vec3(0, 0, 1e20f);
  ResultOptions gather = small();
  gather.final_gather_spp = 4;
  for (const auto& [mesh, failed, why] : {std::tuple{far, std::string(), std::string("the camera's eye is 1e+20")},
                                          std::tuple{quad_with_camera(), std::string("tile 3 was lost"), std::string("tile 3 was lost")}}) {
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    try {
      write_results(file("x"), mesh, {glm::vec3(1), glm::vec3(3)}, gather, {}, nullptr, failed);
      ADD_FAILURE() << "no error for " << why;
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("no image ("), std::string::npos) << what;
      EXPECT_NE(what.find(why), std::string::npos) << what;
      EXPECT_NE(what.find("the solution is kept in " + file("x.ply") + " and " + file("x.glb")), std::string::npos) << what;
    }
    EXPECT_EQ(listing(), (std::vector<std::string>{"x.glb", "x.ply"})) << why;
    std::ifstream ply(file("x.ply"));
    std::string text((std::istreambuf_iterator<char>(ply)), {});
    EXPECT_EQ(text.rfind("ply\n", 0), 0u) << why;
  }
}

// An output name that is a directory (`--out some/dir/`) is refused before the run.
TEST_F(OutputResults, ADirectoryIsNotAnOutputName) {
  EXPECT_THROW(check_output_name(dir_.string() + "/", "--out"), Error);
  EXPECT_NO_THROW(check_output_name(file("x"), "--out"));
}

}  // namespace
}  // namespace sirad
