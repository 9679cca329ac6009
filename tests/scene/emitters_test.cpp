// sirad tests: the lights the direct light samples (scene/emitters.h): a light cut into patches,
// or read back as many faces, is sampled whole; shapes it cannot rebuild fall back to input
// triangles or patches, with the same area.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <gtest/gtest.h>
#include <unistd.h>

#include "io/read_solution.h"
#include "io/write.h"
#include "scene/emitters.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "tests/coincident_scenes.h"

namespace sirad {
namespace {

using glm::dvec3;
using test::ObjBuilder;

const std::string kMtl =
    "newmtl white\nKd 0.5 0.5 0.5\n"
    "newmtl lamp\nKd 0 0 0\nKe 1 1 1\n"
    "newmtl warm\nKd 0 0 0\nKe 2 1 0.5\n";

double emitting_area(const PatchMesh& mesh) {
  double a = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j)
    if (mesh.emits(j)) a += mesh.area[j];
  return a;
}

double total_area(const std::vector<Light>& lights) {
  double a = 0.0;
  for (const Light& l : lights) a += l.area;
  return a;
}

// Whether `light` has exactly the corners `want` (in any order), to `tol`.
bool has_corners(const Light& light, const std::vector<dvec3>& want, double tol) {
  if (static_cast<std::size_t>(light.corners) != want.size()) return false;
  for (const dvec3& w : want) {
    bool found = false;
    for (int k = 0; k < light.corners; ++k) found = found || glm::length(light.p[static_cast<std::size_t>(k)] - w) <= tol;
    if (!found) return false;
  }
  return true;
}

// The Cornell box's light (130 x 105 at y = 548.8, facing down, two input triangles) is one
// parallelogram whatever the meshing cuts it into, with its patches' area; the map of the unit
// square covers it: its image of the square's corners are its corners.
TEST(Lights, TheCornellLightIsOneRectangleAtAnyMeshing) {
  const std::vector<dvec3> corners{{343, 548.8, 227}, {343, 548.8, 332}, {213, 548.8, 332}, {213, 548.8, 227}};
  for (std::size_t patches : {0u, 1000u, 10000u, 40000u}) {
    const PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = patches});
    const std::vector<Light> lights = find_lights(mesh);
    ASSERT_EQ(lights.size(), 1u) << patches << " patches";
    std::size_t light_patches = 0;
    for (std::size_t j = 0; j < mesh.size(); ++j) light_patches += mesh.emits(j);
    EXPECT_GE(light_patches, patches >= 10000 ? 50u : 2u) << patches << " patches";
    const Light& l = lights[0];
    EXPECT_TRUE(has_corners(l, corners, 1e-3)) << patches << " patches";
    EXPECT_NEAR(l.area, 130.0 * 105.0, 1e-3 * 130.0 * 105.0);
    EXPECT_NEAR(l.area, emitting_area(mesh), 1e-4 * emitting_area(mesh));
    EXPECT_NEAR(l.normal.y, -1.0, 1e-6);
    EXPECT_GT(l.emission.x, 0.0);
    std::vector<dvec3> mapped{l.at(0, 0), l.at(1, 0), l.at(1, 1), l.at(0, 1)};
    EXPECT_TRUE(has_corners(l, mapped, 1e-3));
    // Counter-clockwise seen from the front: the map's Jacobian points along the normal.
    EXPECT_GT(glm::dot(glm::cross(l.at(1, 0) - l.at(0, 0), l.at(0, 1) - l.at(0, 0)), l.normal), 0.0);
  }
}

// A solution read back from its PLY (one face per patch, no input triangles) keeps its light whole.
TEST(Lights, ASolutionReadBackKeepsItsLightWhole) {
  const PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 3000});
  const auto path = std::filesystem::temp_directory_path() / fmt::format("sirad_lights_{}.ply", ::getpid());
  write_ply(path.string(), mesh, std::vector<glm::vec3>(mesh.size(), glm::vec3(0.5f)));
  const Solution s = read_solution(path.string());
  std::filesystem::remove(path);
  ASSERT_GT(s.mesh.size(), 100u);
  const std::vector<Light> lights = find_lights(s.mesh);
  ASSERT_EQ(lights.size(), 1u);
  EXPECT_EQ(lights[0].corners, 4);
  EXPECT_NEAR(lights[0].area, emitting_area(s.mesh), 1e-4 * emitting_area(s.mesh));
}

// A triangle light cut into patches is one triangle; two lights of other materials side by side,
// or of one material in two planes, stay two.
TEST(Lights, ShapesAreRebuiltPerMaterialAndPlane) {
  ObjBuilder o;
  o.material("white");
  o.quad({-5, 0, -5}, {-5, 0, 5}, {5, 0, 5}, {5, 0, -5});  // a floor facing +y
  o.material("lamp");
  o.triangle({0, 3, 0}, {2, 3, 0}, {0, 3, 1});  // facing -y
  o.quad({3, 3, 0}, {4, 3, 0}, {4, 3, 1}, {3, 3, 1});  // lamp, facing -y, apart from the triangle
  o.material("warm");
  o.quad({4, 3, 0}, {5, 3, 0}, {5, 3, 1}, {4, 3, 1});  // touches the lamp quad: another material
  o.material("lamp");
  o.quad({-3, 3, 0}, {-3, 2, 0}, {-3, 2, 1}, {-3, 3, 1});  // a wall light facing -x, touching nothing
  const Scene scene = o.scene("lights", kMtl);
  for (std::size_t patches : {0u, 2000u}) {
    const PatchMesh mesh = mesh_scene(scene, {.target_patches = patches});
    const std::vector<Light> lights = find_lights(mesh);
    ASSERT_EQ(lights.size(), 4u) << patches << " patches";
    EXPECT_TRUE(has_corners(lights[0], {{0, 3, 0}, {2, 3, 0}, {0, 3, 1}}, 1e-5));
    EXPECT_TRUE(has_corners(lights[1], {{3, 3, 0}, {4, 3, 0}, {4, 3, 1}, {3, 3, 1}}, 1e-5));
    EXPECT_TRUE(has_corners(lights[2], {{4, 3, 0}, {5, 3, 0}, {5, 3, 1}, {4, 3, 1}}, 1e-5));
    EXPECT_TRUE(has_corners(lights[3], {{-3, 3, 0}, {-3, 2, 0}, {-3, 2, 1}, {-3, 3, 1}}, 1e-5));
    EXPECT_NEAR(lights[0].area, 1.0, 1e-5);
    EXPECT_NEAR(lights[2].emission.x, 2.0, 1e-6);
    EXPECT_NEAR(lights[3].normal.x, -1.0, 1e-6);
    EXPECT_NEAR(total_area(lights), emitting_area(mesh), 1e-4 * emitting_area(mesh));
  }
}

// An L-shaped light (two squares of one material sharing an edge) is no triangle or
// parallelogram: its input triangles are the lights. A disc cut into a fan of triangles about
// its centre (every patch at one vertex) is its triangles. Either way the area is the patches'.
TEST(Lights, OtherShapesFallBackToTheirTriangles) {
  ObjBuilder o;
  o.material("lamp");
  o.quad({0, 3, 0}, {1, 3, 0}, {1, 3, 1}, {0, 3, 1});
  o.quad({1, 3, 0}, {2, 3, 0}, {2, 3, 1}, {1, 3, 1});
  o.quad({1, 3, 1}, {2, 3, 1}, {2, 3, 2}, {1, 3, 2});
  const int fan = 200;
  for (int k = 0; k < fan; ++k) {
    const double a = 2.0 * std::numbers::pi * k / fan, b = 2.0 * std::numbers::pi * (k + 1) / fan;
    o.triangle({10, 3, 0}, {10 + std::cos(a), 3, std::sin(a)}, {10 + std::cos(b), 3, std::sin(b)});
  }
  const Scene scene = o.scene("odd lights", kMtl);
  for (std::size_t patches : {0u, 3000u}) {
    const PatchMesh mesh = mesh_scene(scene, {.target_patches = patches});
    const std::vector<Light> lights = find_lights(mesh);
    EXPECT_EQ(lights.size(), 6u + fan) << patches << " patches";
    for (const Light& l : lights) EXPECT_EQ(l.corners, 3);
    EXPECT_NEAR(total_area(lights), emitting_area(mesh), 1e-4 * emitting_area(mesh));
  }
}

// A light with a hole (a frame of four quads) is not its hull: the fall-back keeps the hole.
TEST(Lights, ALightWithAHoleIsNotItsHull) {
  ObjBuilder o;
  o.material("lamp");
  o.quad({0, 3, 0}, {3, 3, 0}, {3, 3, 1}, {0, 3, 1});
  o.quad({0, 3, 2}, {3, 3, 2}, {3, 3, 3}, {0, 3, 3});
  o.quad({0, 3, 1}, {1, 3, 1}, {1, 3, 2}, {0, 3, 2});
  o.quad({2, 3, 1}, {3, 3, 1}, {3, 3, 2}, {2, 3, 2});
  const PatchMesh mesh = mesh_scene(o.scene("frame", kMtl), {.target_patches = 500});
  const std::vector<Light> lights = find_lights(mesh);
  EXPECT_EQ(lights.size(), 8u);
  EXPECT_NEAR(total_area(lights), 8.0, 1e-5);
}

}  // namespace
}  // namespace sirad
