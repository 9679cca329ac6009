// sirad tests: PLY scenes (scene/ply.h): sirad's own PLY is a scene again, ASCII PLY with
// colours and polygons reads, and hostile PLY files give one clear error and never a crash.
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "io/write.h"
#include "scene/import.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "tests/scene_files.h"
#include "util/error.h"

namespace sirad {
namespace {

namespace fs = std::filesystem;

class PlyFiles : public test::SceneFiles {};

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// PLY scenes (scene/ply.h): the PLY sirad writes is a scene again: the same triangles in
// patch order, each with its patch's reflectance and emission (the per-face properties).
TEST_F(PlyFiles, SiradsOwnPlyIsASceneAgain) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 300});
  mesh.background = glm::vec3(0.25f, 0.5f, 1.5f);
  std::vector<glm::vec3> radiosity(mesh.size(), glm::vec3(0.5f));
  const std::string path = (dir_ / "solved.ply").string();
  write_ply(path, mesh, radiosity);
  Scene s = load_scene(path);
  ASSERT_EQ(s.triangles.size(), mesh.size());
  // The comments keep what an image of it needs: the camera and the background.
  ASSERT_TRUE(s.camera.has_value());
  EXPECT_EQ(camera_spec(*s.camera), camera_spec(*mesh.camera));
  EXPECT_EQ(s.background, mesh.background);
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    for (int k = 0; k < 3; ++k) ASSERT_EQ(s.triangles[j].p[static_cast<std::size_t>(k)], mesh.vertices[mesh.patches[j][static_cast<std::size_t>(k)]]);
    ASSERT_EQ(s.materials[s.triangles[j].material].reflectance, mesh.reflectance(j)) << j;
    ASSERT_EQ(s.materials[s.triangles[j].material].emission, mesh.emission(j)) << j;
  }
  EXPECT_EQ(s.objects, std::vector<std::string>{"solved"});
  // Damaged copies (bytes changed, cut short) load or throw sirad::Error, never anything else.
  const std::string base = slurp(path);
  std::mt19937_64 rng(5);
  for (int round = 0; round < 300; ++round) {
    std::string d = base;
    if (round % 2) d.resize(rng() % d.size());
    else
      for (int k = 0; k < 1 + static_cast<int>(rng() % 6); ++k) d[rng() % d.size()] = static_cast<char>(rng());
    const std::string damaged = write("damaged.ply", d);
    try {
      load_scene(damaged);
    } catch (const Error&) {
    }
  }
}

// An ascii PLY as other tools write it: polygons (fan-triangulated), vertex colours as
// reflectance (bytes, sRGB-decoded), a face with emission.
TEST_F(PlyFiles, AsciiPlyWithColoursAndPolygons) {
  const std::string path = write("quad.ply",
                                 "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 5\nproperty float x\n"
                                 "property float y\nproperty float z\nproperty uchar red\nproperty uchar green\n"
                                 "property uchar blue\nelement face 2\nproperty list uchar int vertex_indices\n"
                                 "property float emission_r\nproperty float emission_g\nproperty float emission_b\n"
                                 "end_header\n0 0 0 255 0 0\n1 0 0 255 0 0\n1 1 0 255 0 0\n0 1 0 255 0 0\n0 0 1 0 0 255\n"
                                 "4 0 1 2 3 0 0 0\n3 0 1 4 2 2 2\n");
  Scene s = load_scene(path);
  ASSERT_EQ(s.triangles.size(), 3u);
  EXPECT_EQ(s.materials[s.triangles[0].material].reflectance, glm::vec3(1.0f, 0.0f, 0.0f));
  EXPECT_EQ(s.materials[s.triangles[2].material].emission, glm::vec3(2.0f));
}

// Bad PLY files: one sirad::Error, one line, naming the file.
TEST_F(PlyFiles, HostilePlyFilesGiveOneLineErrors) {
  const std::string head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                           "element face 1\nproperty list uchar int vertex_indices\nproperty float emission_r\n"
                           "property float emission_g\nproperty float emission_b\nend_header\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"not a ply", "hello\n"},
      {"no end_header", "ply\nformat ascii 1.0\n"},
      {"unknown format", "ply\nformat binary_middle_endian 1.0\nend_header\n"},
      {"count beyond the file", "ply\nformat binary_little_endian 1.0\nelement vertex 99999999999\nproperty float x\nend_header\n"},
      {"truncated binary", "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                           "property float z\nend_header\n\x01\x02"},
      {"index out of range", head + "0 0 0\n1 0 0\n0 1 0\n3 0 1 7 1 1 1\n"},
      {"nan vertex", head + "0 0 nan\n1 0 0\n0 1 0\n3 0 1 2 1 1 1\n"},
      {"not a number", head + "0 0 zero\n1 0 0\n0 1 0\n3 0 1 2 1 1 1\n"},
      {"no emitter", head + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2 0 0 0\n"},
      {"negative emission", head + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2 -1 1 1\n"},
      {"degenerate", head + "0 0 0\n1 0 0\n2 0 0\n3 0 1 2 1 1 1\n"},
      {"two vertices", head + "0 0 0\n1 0 0\n0 1 0\n2 0 1 1 1 1\n"},
      {"no xyz", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float q\nend_header\n1\n"},
      {"unknown type", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n1\n"},
      {"bad camera comment", "ply\nformat ascii 1.0\ncomment sirad camera eye 1 2\nend_header\n"},
      {"bad background comment", "ply\nformat ascii 1.0\ncomment sirad background 1 nan 2\nend_header\n"},
      {"negative background", "ply\nformat ascii 1.0\ncomment sirad background 1 -1 2\nend_header\n"},
  };
  for (const auto& [what, text] : cases) {
    SCOPED_TRACE(what);
    expect_refused("bad.ply", text);
  }
}

}  // namespace
}  // namespace sirad
