// sirad tests: the scene encoding nodes receive: a round trip meshes to the same content hash;
// truncated, padded and tampered bytes are refused with a one-line reason.
#include <gtest/gtest.h>

#include "scene/encoding.h"
#include "scene/mesh.h"
#include "util/error.h"

namespace sirad {
namespace {

TEST(SceneIo, RoundTripMeshesToTheSameHash) {
  for (const Scene& scene : {builtin_cornell(), builtin_furnace()}) {
    std::string bytes = encode_scene(scene);
    Scene back = decode_scene(bytes, "wire");
    EXPECT_EQ(back.name, scene.name);
    ASSERT_EQ(back.triangles.size(), scene.triangles.size());
    EXPECT_EQ(back.camera.has_value(), scene.camera.has_value());
    EXPECT_EQ(mesh_scene(back, {.target_patches = 2000}).hash, mesh_scene(scene, {.target_patches = 2000}).hash);
    EXPECT_EQ(encode_scene(back), bytes);
  }
}

// Faces no light reaches (Triangle::unlit) travel with the scene, so that a node meshes them
// whole as the coordinator does, and so do the pieces over a lamp (Triangle::in_gap) and the
// strips along its rim (Triangle::whole, also meshed whole): the v2
// encoding, written only when a face is marked (a scene without marks stays v1, which every node
// reads).
TEST(SceneIo, FacesNoLightReachesTravelWithTheScene) {
  Scene scene = builtin_cornell();
  EXPECT_EQ(encode_scene(scene).substr(0, 14), "sirad-scene-v1");
  scene.triangles[0].unlit = scene.triangles[5].unlit = true;
  scene.triangles[5].in_gap = scene.triangles[6].in_gap = true;
  scene.triangles[7].whole = true;
  const std::string bytes = encode_scene(scene);
  EXPECT_EQ(bytes.substr(0, 14), "sirad-scene-v2");
  Scene back = decode_scene(bytes, "wire");
  ASSERT_EQ(back.triangles.size(), scene.triangles.size());
  for (std::size_t i = 0; i < scene.triangles.size(); ++i) {
    EXPECT_EQ(back.triangles[i].unlit, i == 0 || i == 5) << i;
    EXPECT_EQ(back.triangles[i].in_gap, i == 5 || i == 6) << i;
    EXPECT_EQ(back.triangles[i].whole, i == 7) << i;
  }
  const PatchMesh here = mesh_scene(scene, {.target_patches = 2000}), there = mesh_scene(back, {.target_patches = 2000});
  EXPECT_EQ(here.hash, there.hash);
  EXPECT_EQ(here.in_gap, there.in_gap);
  EXPECT_NE(here.hash, mesh_scene(builtin_cornell(), {.target_patches = 2000}).hash);
  EXPECT_EQ(encode_scene(back), bytes);
}

void expect_refused(const std::string& bytes, const std::string& reason) {
  try {
    decode_scene(bytes, "wire");
    ADD_FAILURE() << "accepted; expected: " << reason;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
  }
}

TEST(SceneIo, MalformedBytesAreRefused) {
  std::string good = encode_scene(builtin_cornell());
  expect_refused("", "not a sirad scene");
  expect_refused("garbage that is long enough to read", "not a sirad scene");
  for (std::size_t cut : {good.size() - 1, good.size() / 2, std::size_t{20}})
    expect_refused(good.substr(0, cut), "truncated");
  expect_refused(good + "x", "after the scene");
  // A vertex made NaN: the first triangle's first coordinate.
  Scene s = builtin_cornell();
  s.triangles[0].p[0].x = std::numeric_limits<float>::quiet_NaN();
  expect_refused(encode_scene(s), "non-finite vertex");
  s = builtin_cornell();
  s.triangles[3].material = 99;
  expect_refused(encode_scene(s), "uses material 99");
  s = builtin_cornell();
  s.materials[0].reflectance.y = 1.5f;
  expect_refused(encode_scene(s), "outside [0, 1]");
  s = builtin_cornell();
  for (auto& m : s.materials) m.emission = glm::vec3(0.0f);
  expect_refused(encode_scene(s), "no emitter");
  // Flags: only bits 0 (unlit), 1 (in a gap) and 2 (whole) are known. The first triangle's flags word follows its 3 vertices,
  // material and line, after the tag, the name and the materials.
  s = builtin_cornell();
  s.triangles[0].unlit = true;
  std::string flagged = encode_scene(s);
  std::size_t at = 14 + 4 + s.name.size() + 4;
  for (const Material& m : s.materials) at += 4 + m.name.size() + 24;
  at += 4 + 36 + 8;
  ASSERT_EQ(flagged[at], 1);
  flagged[at] = 9;
  expect_refused(flagged, "unknown flags 0x9");
}

}  // namespace
}  // namespace sirad
