// sirad tests: meshing (subdivision counts, edge lengths, area, target counts, welding, hash).
#include "scene/mesh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "util/error.h"

namespace sirad {
namespace {

double edge_length(const glm::vec3& a, const glm::vec3& b) {
  return glm::length(glm::dvec3(a) - glm::dvec3(b));
}

double longest_edge(const Triangle& t) {
  return std::max(
      {edge_length(t.p[0], t.p[1]), edge_length(t.p[1], t.p[2]), edge_length(t.p[2], t.p[0])});
}

double triangle_area(const Triangle& t) {
  const glm::dvec3 a(t.p[0]), b(t.p[1]), c(t.p[2]);
  return 0.5 * glm::length(glm::cross(b - a, c - a));
}

glm::dvec3 triangle_normal(const Triangle& t) {
  const glm::dvec3 a(t.p[0]), b(t.p[1]), c(t.p[2]);
  return glm::normalize(glm::cross(b - a, c - a));
}

// Patches per input triangle, in order.
std::vector<std::size_t> patches_per_triangle(const PatchMesh& mesh, std::size_t triangles) {
  std::vector<std::size_t> count(triangles, 0);
  for (uint32_t t : mesh.source_triangle) ++count.at(t);
  return count;
}

// The unit square z = 0 as two triangles (CCW from +z), emitting.
Scene unit_square() {
  Scene s;
  s.name = "square";
  s.materials.push_back({"m", glm::vec3(0.5f), glm::vec3(1.0f)});
  s.triangles.push_back({{glm::vec3(0, 0, 0), glm::vec3(1, 0, 0), glm::vec3(1, 1, 0)}, 0, 0});
  s.triangles.push_back({{glm::vec3(0, 0, 0), glm::vec3(1, 1, 0), glm::vec3(0, 1, 0)}, 0, 0});
  return s;
}

// The Cornell box without its blocks: faces that meet only at their edges, none split.
Scene cornell_without_blocks() {
  Scene scene = builtin_cornell();
  std::erase_if(scene.triangles, [&](const Triangle& t) { return scene.objects.at(t.object).ends_with("_block"); });
  return scene;
}

// A triangle gets n x n patches; the floor, where the blocks stand, is also split along their
// feet (tests/scene/contacts_test.cpp). Faces that meet only along their edges are not.
TEST(MeshSubdivision, MaxEdgeGivesNSquaredPatchesAndShortEdges) {
  const Scene scene = builtin_cornell();
  for (double max_edge : {1000.0, 120.0, 37.5}) {
    MeshOptions options;
    options.max_edge = max_edge;
    const PatchMesh mesh = mesh_scene(scene, options);
    const auto counts = patches_per_triangle(mesh, scene.triangles.size());
    for (std::size_t t = 0; t < scene.triangles.size(); ++t) {
      if (scene.objects.at(scene.triangles[t].object) == "floor") continue;
      const auto n = static_cast<std::size_t>(
          std::max(1.0, std::ceil(longest_edge(scene.triangles[t]) / max_edge)));
      EXPECT_EQ(counts[t], n * n) << "triangle " << t << ", max_edge " << max_edge;
    }
    // Source triangles appear in input order.
    EXPECT_TRUE(std::is_sorted(mesh.source_triangle.begin(), mesh.source_triangle.end()));
    for (const auto& p : mesh.patches)
      for (int k = 0; k < 3; ++k)
        EXPECT_LE(edge_length(mesh.vertices[p[k]], mesh.vertices[p[(k + 1) % 3]]),
                  max_edge * (1 + 1e-5));
  }
}

// A sliver (longest edge squared over 16 x its area) is subdivided by 4 x the square root of its
// area instead of its longest edge, so that its pieces (slivers of its shape) are no smaller in
// area than about a quarter of a well-shaped patch's; right and equilateral triangles are
// subdivided by their longest edge as before.
TEST(MeshSubdivision, SliversAreSubdividedByTheirArea) {
  const Scene scene = parse_obj("sliver.obj",
                                "mtllib m.mtl\nusemtl e\n"
                                "v 0 0 0\nv 1 0 0\nv 0 0.01 0\nf 1 2 3\n"         // 1 m x 1 cm
                                "v 0 0 1\nv 1 0 1\nv 0 1 1\nf 4 5 6\n"             // right, legs 1 m
                                "v 0 0 2\nv 1 0 2\nv 0.5 0.8660254 2\nf 7 8 9\n",  // equilateral
                                {{"m.mtl", "newmtl e\nKd 0.5 0.5 0.5\nKe 1 1 1\n"}});
  const PatchMesh mesh = mesh_scene(scene, {.max_edge = 0.1});
  const auto counts = patches_per_triangle(mesh, scene.triangles.size());
  EXPECT_EQ(counts[0], 3u * 3u);    // ceil(4 sqrt(0.005) / 0.1) = 3, not ceil(1 / 0.1) = 10
  EXPECT_EQ(counts[1], 15u * 15u);  // ceil(sqrt(2) / 0.1)
  EXPECT_EQ(counts[2], 10u * 10u);
}

TEST(MeshSubdivision, SubTriangleOrderAndOrientation) {
  // One triangle split n = 3 ways: the first patch is the corner at a, the last the one at c.
  Scene s = unit_square();
  s.triangles.resize(1);
  MeshOptions options;
  options.max_edge = std::sqrt(2.0) / 3.0 + 1e-9;
  const PatchMesh mesh = mesh_scene(s, options);
  ASSERT_EQ(mesh.size(), 9u);
  const auto& first = mesh.patches.front();
  EXPECT_EQ(mesh.vertices[first[0]], glm::vec3(0, 0, 0));
  EXPECT_EQ(mesh.vertices[first[1]], glm::vec3(1.0f / 3.0f, 0, 0));
  EXPECT_EQ(mesh.vertices[first[2]], glm::vec3(1.0f / 3.0f, 1.0f / 3.0f, 0));
  EXPECT_EQ(mesh.vertices[mesh.patches.back()[2]], glm::vec3(1, 1, 0));
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    EXPECT_EQ(mesh.normal[j], glm::vec3(0, 0, 1));
    EXPECT_NEAR(mesh.area[j], 0.5 / 9.0, 1e-7);
  }
}

TEST(MeshSubdivision, AreaIsPreserved) {
  const Scene scene = cornell_without_blocks();
  double input = 0.0;
  for (const Triangle& t : scene.triangles) input += triangle_area(t);
  for (double max_edge : {0.0, 80.0, 13.0}) {
    MeshOptions options;
    options.max_edge = max_edge;
    const PatchMesh mesh = mesh_scene(scene, options);
    double total = 0.0;
    for (float a : mesh.area) {
      EXPECT_GT(a, 0.0f);
      total += a;
    }
    EXPECT_NEAR(total / input, 1.0, 1e-5) << "max_edge " << max_edge;
  }
}

// Every patch count reachable by some max_edge, found at each step of every triangle's n
// (edges L / k) and at the neighbouring doubles.
std::set<std::size_t> achievable_counts(const Scene& scene, std::size_t up_to_n) {
  std::vector<double> longest;
  for (const Triangle& t : scene.triangles) longest.push_back(longest_edge(t));
  std::set<std::size_t> counts;
  for (double l : longest)
    for (std::size_t k = 1; k <= up_to_n; ++k)
      for (double e : {std::nextafter(l / k, 0.0), l / k, std::nextafter(l / k, 1e300)}) {
        std::size_t total = 0;
        for (double m : longest) {
          const auto n = static_cast<std::size_t>(std::max(1.0, std::ceil(m / e)));
          total += n * n;
        }
        counts.insert(total);
      }
  return counts;
}

TEST(MeshTarget, ClosestAchievableCount) {
  const Scene scene = cornell_without_blocks();
  const std::set<std::size_t> counts = achievable_counts(scene, 80);
  for (std::size_t target : {39u, 100u, 777u, 5000u, 12345u}) {
    // The closest achievable count, the smaller one on a tie.
    std::size_t best = 0;
    for (std::size_t c : counts) {
      const auto d = [&](std::size_t x) { return x > target ? x - target : target - x; };
      if (best == 0 || d(c) < d(best)) best = c;
    }
    MeshOptions options;
    options.target_patches = target;
    EXPECT_EQ(mesh_scene(scene, options).size(), best) << "target " << target;
  }
  // Fewer than the input triangles: one patch each.
  MeshOptions few;
  few.target_patches = 5;
  EXPECT_EQ(mesh_scene(scene, few).size(), scene.triangles.size());
}

// A face no light reaches (Triangle::unlit) stays one patch, and the target's patches go to the
// others; a scene of such faces only is meshed one patch a face.
TEST(MeshTarget, FacesNoLightReachesStayWhole) {
  Scene scene = builtin_cornell();
  auto per_triangle = [&] {
    std::vector<std::size_t> per(scene.triangles.size(), 0);
    for (uint32_t t : mesh_scene(scene, {.target_patches = 3000}).source_triangle) ++per[t];
    return per;
  };
  const std::vector<std::size_t> before = per_triangle();
  const std::size_t marked[] = {0, 1, 7};
  for (std::size_t i : marked) scene.triangles[i].unlit = true;
  const PatchMesh mesh = mesh_scene(scene, {.target_patches = 3000});
  const std::vector<std::size_t> per = per_triangle();
  for (std::size_t i = 0; i < per.size(); ++i) {
    if (scene.triangles[i].unlit) {
      EXPECT_EQ(per[i], 1u) << i;
    } else {
      EXPECT_GE(per[i], before[i]) << i;
      EXPECT_GT(per[i], 1u) << i;
    }
  }
  EXPECT_NEAR(static_cast<double>(mesh.size()), 3000.0, 150.0);
  for (Triangle& t : scene.triangles) t.unlit = true;
  EXPECT_EQ(mesh_scene(scene, {.target_patches = 3000}).size(), scene.triangles.size());
  EXPECT_EQ(mesh_scene(scene, {.max_edge = 1.0}).size(), scene.triangles.size());
}

TEST(MeshTarget, BadOptionsAreErrors) {
  const Scene scene = builtin_cornell();
  const auto message = [&](const MeshOptions& o) {
    try {
      mesh_scene(scene, o);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  MeshOptions o;
  o.max_edge = -1.0;
  EXPECT_NE(message(o).find("max_edge -1"), std::string::npos) << message(o);
  o.max_edge = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(message(o).find("max_edge nan"), std::string::npos) << message(o);
  o.max_edge = 10.0;
  o.target_patches = 100;
  EXPECT_NE(message(o).find("not both"), std::string::npos) << message(o);
  o = MeshOptions{};
  o.target_patches = std::size_t{1} << 31;
  EXPECT_NE(message(o).find("exceeds 2^31 - 1"), std::string::npos) << message(o);
  o = MeshOptions{};
  o.max_edge = 1e-6;  // about 10^17 patches: refused before allocating
  EXPECT_NE(message(o).find("more than 2^31 - 1"), std::string::npos) << message(o);
}

TEST(MeshHash, StableOrderAndHash) {
  const Scene scene = builtin_cornell();
  MeshOptions options;
  options.target_patches = 2000;
  const PatchMesh a = mesh_scene(scene, options), b = mesh_scene(scene, options);
  EXPECT_EQ(a.vertices, b.vertices);
  EXPECT_EQ(a.patches, b.patches);
  EXPECT_EQ(a.material, b.material);
  EXPECT_EQ(a.hash, b.hash);
  EXPECT_EQ(a.hash, content_hash(a));
  ASSERT_EQ(a.hash.size(), 32u);
  EXPECT_EQ(a.hash.find_first_not_of("0123456789abcdef"), std::string::npos);
}

TEST(MeshHash, ChangesWithContent) {
  const Scene scene = builtin_cornell();
  const PatchMesh mesh = mesh_scene(scene, {});
  // One reflectance channel of one material, in the scene or in the mesh.
  Scene brighter = scene;
  brighter.materials[0].reflectance.y += 0.01f;
  EXPECT_NE(mesh_scene(brighter, {}).hash, mesh.hash);
  PatchMesh edited = mesh;
  edited.materials.back().reflectance.x = 0.5f;
  EXPECT_NE(content_hash(edited), mesh.hash);
  // One vertex coordinate.
  edited = mesh;
  edited.vertices[3].z = std::nextafter(edited.vertices[3].z, 1e9f);
  EXPECT_NE(content_hash(edited), mesh.hash);
  // The background.
  edited = mesh;
  edited.background = glm::vec3(0.1f);
  EXPECT_NE(content_hash(edited), mesh.hash);
  // Names are not content.
  edited = mesh;
  edited.materials[0].name = "renamed";
  EXPECT_EQ(content_hash(edited), mesh.hash);
}

TEST(MeshWeld, SharedEdgesAndDuplicatedVertices) {
  // Two triangles sharing the diagonal, n = 4 each (longest edge sqrt(2) / 0.4 -> 4).
  MeshOptions options;
  options.max_edge = 0.4;
  const PatchMesh mesh = mesh_scene(unit_square(), options);
  EXPECT_EQ(mesh.size(), 32u);
  EXPECT_EQ(mesh.vertices.size(), 25u);
  // The diagonal written in opposite directions by the two triangles still welds.
  Scene flipped = unit_square();
  flipped.triangles[1].p = {glm::vec3(1, 1, 0), glm::vec3(0, 1, 0), glm::vec3(0, 0, 0)};
  EXPECT_EQ(mesh_scene(flipped, options).vertices.size(), 25u);
  // An OBJ that repeats the vertices for each face.
  const Scene obj = parse_obj("dup.obj",
                              "mtllib m.mtl\nusemtl e\n"
                              "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n"
                              "v 0 0 0\nv 1 1 0\nv 0 1 0\nf 4 5 6\n",
                              {{"m.mtl", "newmtl e\nKd 0.5 0.5 0.5\nKe 1 1 1\n"}});
  EXPECT_EQ(mesh_scene(obj, {}).vertices.size(), 4u);
  EXPECT_EQ(mesh_scene(obj, options).vertices.size(), 25u);
}

TEST(MeshCornell, NormalsFollowSourceAndBoundContainsAll) {
  const Scene scene = builtin_cornell();
  MeshOptions options;
  options.target_patches = 5000;
  const PatchMesh mesh = mesh_scene(scene, options);
  EXPECT_NEAR(double(mesh.size()), 5000.0, 500.0);
  ASSERT_EQ(mesh.normal.size(), mesh.size());
  ASSERT_EQ(mesh.area.size(), mesh.size());
  ASSERT_EQ(mesh.material.size(), mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    const Triangle& source = scene.triangles[mesh.source_triangle[j]];
    EXPECT_EQ(mesh.material[j], source.material);
    EXPECT_GT(glm::dot(glm::dvec3(mesh.normal[j]), triangle_normal(source)), 1.0 - 1e-5)
        << "patch " << j;
    EXPECT_NEAR(glm::length(glm::dvec3(mesh.normal[j])), 1.0, 1e-6);
  }
  for (const glm::vec3& v : mesh.vertices)
    EXPECT_LT(glm::length(glm::dvec3(v) - glm::dvec3(mesh.bound_center)),
              double(mesh.bound_radius));
  EXPECT_LT(mesh.bound_radius,
            1.01f * 0.5f * std::sqrt(556.0f * 556.0f + 548.8f * 548.8f + 559.2f * 559.2f));
  EXPECT_EQ(mesh.materials.size(), scene.materials.size());
  ASSERT_TRUE(mesh.camera.has_value());
  EXPECT_EQ(mesh.camera->eye, scene.camera->eye);
}

TEST(MeshFurnace, InwardNormalsAndTotalArea) {
  MeshOptions options;
  options.target_patches = 1200;
  const PatchMesh mesh = mesh_scene(builtin_furnace(), options);
  double total = 0.0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    total += mesh.area[j];
    const auto& p = mesh.patches[j];
    const glm::dvec3 centroid = (glm::dvec3(mesh.vertices[p[0]]) + glm::dvec3(mesh.vertices[p[1]]) +
                                 glm::dvec3(mesh.vertices[p[2]])) /
                                3.0;
    EXPECT_GT(glm::dot(glm::dvec3(mesh.normal[j]), glm::dvec3(0.5) - centroid), 0.0);
  }
  EXPECT_NEAR(total, 6.0, 6e-5);
}

}  // namespace
}  // namespace sirad

namespace sirad {
namespace {

std::string mesh_error(const Scene& s, const MeshOptions& o = {}) {
  try {
    mesh_scene(s, o);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// Values the float pipeline cannot carry are refused at meshing, whatever the scene's format:
// an emission of 1e38 (which gave an all-NaN result before: scene/mesh.cpp's derivation of the
// 1e20 bound), a brightest light below 1e-20, emission x area above 1e30, and a reflectance
// outside [0, 1]. The bounds themselves are accepted.
TEST(MeshRadiometry, ValuesBeyondTheFloatPipelineAreRefused) {
  Scene s = unit_square();
  s.materials[0].emission = glm::vec3(1e38f, 0, 0);
  EXPECT_NE(mesh_error(s).find("emission component 0 is 1e+38, outside [0, 1e+20]"), std::string::npos) << mesh_error(s);
  s.materials[0].emission = glm::vec3(1e20f);
  EXPECT_EQ(mesh_error(s), "");
  s.materials[0].emission = glm::vec3(1e-30f);
  EXPECT_NE(mesh_error(s).find("below 1e-20"), std::string::npos) << mesh_error(s);
  s.materials[0].emission = glm::vec3(1e19f);
  for (Triangle& t : s.triangles)
    for (glm::vec3& p : t.p) p *= 1e6f;  // area 1e12: power 1e31
  EXPECT_NE(mesh_error(s).find("emission x area"), std::string::npos) << mesh_error(s);
  s = unit_square();
  s.materials[0].reflectance = glm::vec3(0.5f, std::numeric_limits<float>::quiet_NaN(), 0.5f);
  EXPECT_NE(mesh_error(s).find("reflectance component 1"), std::string::npos) << mesh_error(s);
  s = unit_square();
  s.background = glm::vec3(std::numeric_limits<float>::infinity());
  EXPECT_NE(mesh_error(s).find("background"), std::string::npos) << mesh_error(s);
}

// A node meshes a coordinator's scene to no more patches than the run says it has: refused
// before anything is allocated (a lying target_patches cost 2 GB before).
TEST(MeshTarget, MaxPatchesRefusesBeforeAllocating) {
  MeshOptions o;
  o.target_patches = 50'000'000;
  o.max_patches = 300;
  EXPECT_NE(mesh_error(unit_square(), o).find("more than the 300 allowed"), std::string::npos) << mesh_error(unit_square(), o);
  o.target_patches = 200;
  EXPECT_EQ(mesh_error(unit_square(), o), "");
}

}  // namespace
}  // namespace sirad
