// sirad tests: scene import (built-ins, OBJ/MTL files, the camera line, rejection of bad input).
#include "scene/scene.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <random>
#include <string>
#include <vector>

#include "tests/coincident_scenes.h"
#include "util/error.h"
#include "util/resources.h"

namespace sirad {
namespace {

namespace fs = std::filesystem;

glm::dvec3 normal_of(const Triangle& t) {
  return glm::cross(glm::dvec3(t.p[1]) - glm::dvec3(t.p[0]),
                    glm::dvec3(t.p[2]) - glm::dvec3(t.p[0]));
}

// A fresh directory under the system temp directory, removed with everything in it.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() /
            ("sirad-scene-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  // Writes `text` to `name` in the directory and returns its path as a string.
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(path_ / name, std::ios::binary) << text;
    return (path_ / name).string();
  }
  std::string path(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

// The message of the sirad::Error that `f` throws ("" and a test failure if none).
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "no sirad::Error thrown";
  return "";
}

const std::string kMtl =
    "newmtl white\nKd 0.5 0.5 0.5\n"
    "newmtl light\nKd 0.5 0.5 0.5\nKe 1 2 3\n";

// A unit quad lit by itself, with MTL: the smallest valid scene. Lines 1..8.
const std::string kQuad =
    "mtllib s.mtl\n"
    "v 0 0 0\n"
    "v 1 0 0\n"
    "v 1 1 0\n"
    "v 0 1 0\n"
    "usemtl light\n"
    "f 1 2 3\n"
    "f 1 3 4\n";

// Writes `obj` (and kMtl as s.mtl) into `dir` and returns the message of loading it.
std::string load_error(const TempDir& dir, const std::string& obj, const std::string& mtl = kMtl,
                       const ImportOptions& options = {}) {
  dir.write("s.mtl", mtl);
  const std::string path = dir.write("s.obj", obj);
  return error_of([&] { load_scene(path, options); });
}

TEST(SceneBuiltin, CornellTrianglesMaterialsCamera) {
  const Scene s = builtin_cornell();
  EXPECT_EQ(s.name, "cornell");
  // Every face of the OBJ is a quad: two triangles each.
  const std::string obj(resource("scenes/cornell_box.obj"));
  std::size_t quads = 0;
  for (std::size_t pos = 0; (pos = obj.find("\nf ", pos)) != std::string::npos; ++pos) ++quads;
  EXPECT_EQ(quads, 19u);
  EXPECT_EQ(s.triangles.size(), 2 * quads);

  int emitters = 0;
  for (const Material& m : s.materials)
    if (m.emission.x > 0 || m.emission.y > 0 || m.emission.z > 0) {
      ++emitters;
      EXPECT_EQ(m.name, "light");
      EXPECT_EQ(m.emission, glm::vec3(17, 12, 4));
    }
  EXPECT_EQ(emitters, 1);

  ASSERT_TRUE(s.camera.has_value());
  EXPECT_EQ(s.camera->eye, glm::vec3(278, 273, -800));
  EXPECT_EQ(s.camera->look_at, glm::vec3(278, 273, 0));
  EXPECT_EQ(s.camera->up, glm::vec3(0, 1, 0));
  EXPECT_FLOAT_EQ(s.camera->vfov_deg, 39.3077f);

  // The floor (all vertices at y = 0) faces up into the room; every triangle has a line.
  int floor = 0;
  for (const Triangle& t : s.triangles) {
    EXPECT_GT(t.source_line, 0u);
    if (t.p[0].y == 0 && t.p[1].y == 0 && t.p[2].y == 0) {
      ++floor;
      const glm::dvec3 n = glm::normalize(normal_of(t));
      EXPECT_NEAR(n.y, 1.0, 1e-12);
    }
  }
  EXPECT_EQ(floor, 2);
}

TEST(SceneBuiltin, FurnaceIsAClosedInwardCube) {
  const Scene s = builtin_furnace();
  EXPECT_EQ(s.name, "furnace");
  ASSERT_EQ(s.triangles.size(), 12u);
  ASSERT_EQ(s.materials.size(), 1u);
  EXPECT_EQ(s.materials[0].emission, glm::vec3(1.0f));
  EXPECT_EQ(s.materials[0].reflectance, glm::vec3(0.5f));
  double area = 0.0;
  const glm::dvec3 centre(0.5);
  for (const Triangle& t : s.triangles) {
    const glm::dvec3 n = normal_of(t);
    area += 0.5 * glm::length(n);
    // The normal points from the face towards the centre (at distance 0.5 along it).
    EXPECT_NEAR(glm::dot(glm::normalize(n), centre - glm::dvec3(t.p[0])), 0.5, 1e-12);
  }
  EXPECT_NEAR(area, 6.0, 1e-12);
  ASSERT_TRUE(s.camera.has_value());
  EXPECT_EQ(s.camera->eye, glm::vec3(0.5f, 0.5f, 0.05f));
  EXPECT_EQ(s.camera->vfov_deg, 90.0f);
}

TEST(SceneBuiltin, LoadSceneByName) {
  EXPECT_EQ(load_scene("cornell").triangles.size(), 38u);
  EXPECT_EQ(load_scene("furnace").triangles.size(), 12u);
  EXPECT_GT(load_scene("bright-room").triangles.size(), 0u);
  EXPECT_GT(load_scene("three-lights").triangles.size(), 0u);
  EXPECT_EQ(builtin_scene_names(), (std::vector<std::string>{"cornell", "furnace", "bright-room", "three-lights"}));
}

TEST(SceneFile, LoadsObjWithMtlCameraAndLines) {
  TempDir dir;
  dir.write("s.mtl", kMtl);
  const std::string path =
      dir.write("S.OBJ", "# sirad camera fov 45 up 0 1 0 look 0.5 0.5 0 eye 0.5 0.5 3\n" + kQuad +
                             "usemtl white\nv 0 0 1\nf -1 1 2\n");
  const Scene s = load_scene(path);
  EXPECT_EQ(s.name, path);
  ASSERT_EQ(s.triangles.size(), 3u);
  // Materials in order of first use; lines of the faces (camera line shifts them by one).
  ASSERT_EQ(s.materials.size(), 2u);
  EXPECT_EQ(s.materials[0].name, "light");
  EXPECT_EQ(s.materials[0].emission, glm::vec3(1, 2, 3));
  EXPECT_EQ(s.materials[1].name, "white");
  EXPECT_EQ(s.triangles[0].source_line, 8u);
  EXPECT_EQ(s.triangles[1].source_line, 9u);
  EXPECT_EQ(s.triangles[2].source_line, 12u);
  EXPECT_EQ(s.triangles[2].material, 1u);
  EXPECT_EQ(s.triangles[2].p[0], glm::vec3(0, 0, 1));  // relative index -1
  ASSERT_TRUE(s.camera.has_value());
  EXPECT_EQ(s.camera->eye, glm::vec3(0.5f, 0.5f, 3.0f));
  EXPECT_EQ(s.camera->vfov_deg, 45.0f);
}

TEST(SceneFile, ParseObjPolygonsAndDefaultMaterial) {
  // A pentagon fan-triangulated into 3 triangles with the default material, plus an emitter 1 m
  // above it (on it, it would cut the pentagon: scene.h cut_along_gaps).
  const std::string obj =
      "mtllib lib.mtl\n"
      "v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 2 0\nv -1 1 0\nv 0 0 1\nv 2 0 1\nv 1 2 1\n"
      "f 1 2 3 4 5\n"
      "usemtl light\n"
      "f 6/1/1 7/2/2 8//4\n";
  const Scene s = parse_obj("mem", obj, {{"lib.mtl", kMtl}});
  ASSERT_EQ(s.triangles.size(), 4u);
  EXPECT_FALSE(s.camera.has_value());
  EXPECT_EQ(s.materials[0].reflectance, glm::vec3(0.8f));
  EXPECT_EQ(s.materials[0].emission, glm::vec3(0.0f));
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(s.triangles[k].p[0], glm::vec3(0, 0, 0));  // fan around the first vertex
    EXPECT_GT(normal_of(s.triangles[k]).z, 0.0);
  }
  EXPECT_EQ(s.triangles[3].material, 1u);
}

// Expects `message` to contain every one of `parts`.
void expect_parts(const std::string& message, const std::vector<std::string>& parts) {
  for (const std::string& part : parts)
    EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' not in: " << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
}

// Faces as Blender's OBJ exporter writes them: a wall with a door cut by a Boolean is one concave
// 8-cornered face (its fan from corner 0 would close the doorway), and an empty material slot is
// `usemtl` with no name: those faces take the default material, and a warning names the line.
TEST(SceneFile, ObjFacesAsBlenderWritesThem) {
  const std::string obj =
      "mtllib lib.mtl\n"
      "o Wall\n"
      "v 0 0 0\nv 1 0 0\nv 1 2.1 0\nv 1.9 2.1 0\nv 1.9 0 0\nv 4 0 0\nv 4 2.6 0\nv 0 2.6 0\n"
      "usemtl white\n"
      "f 1 2 3 4 5 6 7 8\n"
      "o Lamp\nusemtl light\nv 0 0 1\nv 0 1 1\nv 1 0 1\nf 9 10 11\n"
      "o Wardrobe\nusemtl \nf 9 11 10\n";
  const Scene s = parse_obj("mem", obj, {{"lib.mtl", kMtl}});
  std::size_t wall = 0;
  double area = 0.0;
  for (const Triangle& t : s.triangles) {
    if (t.object != 1u) continue;
    ++wall;
    const glm::dvec3 n = normal_of(t);
    EXPECT_GT(n.z, 0.0);
    area += glm::length(n) / 2.0;
    // No triangle covers the doorway, x in (1, 1.9) below 2.1.
    const glm::dvec3 c = (glm::dvec3(t.p[0]) + glm::dvec3(t.p[1]) + glm::dvec3(t.p[2])) / 3.0;
    EXPECT_FALSE(c.x > 1.0 && c.x < 1.9 && c.y < 2.1) << c.x << " " << c.y;
    EXPECT_EQ(t.source_line, 12u);
  }
  EXPECT_EQ(wall, 6u);
  EXPECT_NEAR(area, 4.0 * 2.6 - 0.9 * 2.1, 1e-5);
  const Triangle& wardrobe = s.triangles.back();
  EXPECT_EQ(s.objects.at(wardrobe.object), "Wardrobe");
  EXPECT_EQ(s.materials.at(wardrobe.material).name, "default");
  EXPECT_EQ(s.materials.at(wardrobe.material).reflectance, glm::vec3(0.8f));
  ASSERT_EQ(s.warnings.size(), 1u);
  expect_parts(s.warnings[0], {"mem:21:", "1 triangles have no material", "default"});

  // A face that crosses itself is refused with its line, never cut into triangles outside it.
  try {
    parse_obj("mem", "mtllib lib.mtl\nusemtl light\nv 0 0 0\nv 2 2 0\nv 2 0 0\nv 1 3 0\nv 0 2 0\nv 1 -1 0\nf 1 2 3 4 5 6\n",
              {{"lib.mtl", kMtl}});
    ADD_FAILURE() << "a face that crosses itself was taken";
  } catch (const Error& e) {
    expect_parts(e.what(), {"mem:9:", "crosses itself"});
  }
}

// `o` and `g` name the faces that follow; a material with `sirad_two_sided 1` gets a reversed
// twin (same corners, opposite winding) where that side sees light, as does every material under
// ImportOptions::two_sided; twins come before every original; a texture map is noted, not
// silently dropped. Here a lamp 1 m above a floor faces up: its twin faces the floor and is kept,
// while the floor's twins would face down into nothing and are not made.
TEST(SceneFile, ObjectsTwoSidedMaterialsAndTextureNotes) {
  const std::string obj =
      "mtllib lib.mtl\n"
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0.2 0.2 1\nv 0.8 0.2 1\nv 0.2 0.8 1\n"
      "o Floor\nusemtl plain\nf 1 2 3\n"
      "g Lamp shade\nusemtl glow\nf 5 6 7\n"
      "o Floor\nusemtl plain\nf 2 4 3\n";
  const std::string mtl =
      "newmtl plain\nKd 0.5 0.5 0.5\nmap_Kd wood.png\n"
      "newmtl glow\nKd 0.1 0.1 0.1\nKe 2 2 2\nsirad_two_sided 1\n";
  const Scene s = parse_obj("mem", obj, {{"lib.mtl", mtl}});
  ASSERT_EQ(s.objects, (std::vector<std::string>{"(unnamed)", "Floor", "Lamp shade"}));
  ASSERT_EQ(s.triangles.size(), 4u);
  EXPECT_EQ(s.triangles[0].object, 2u);  // the lamp's twin first
  EXPECT_EQ(s.triangles[1].object, 1u);
  EXPECT_EQ(s.triangles[2].object, 2u);
  EXPECT_EQ(s.triangles[3].object, 1u);
  EXPECT_FALSE(s.materials[0].two_sided);
  EXPECT_TRUE(s.materials[1].two_sided);
  // The glowing triangle and its twin: the same corners, the other way round.
  EXPECT_EQ(s.triangles[0].p[0], s.triangles[2].p[0]);
  EXPECT_EQ(s.triangles[0].p[1], s.triangles[2].p[2]);
  EXPECT_EQ(s.triangles[0].p[2], s.triangles[2].p[1]);
  EXPECT_NEAR(glm::dot(glm::normalize(normal_of(s.triangles[0])), glm::normalize(normal_of(s.triangles[2]))), -1.0, 1e-9);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("'plain'"), std::string::npos) << s.warnings[0];
  EXPECT_NE(s.warnings[0].find("wood.png"), std::string::npos) << s.warnings[0];

  // Everything two-sided: the floor's backs face down into nothing and get no twin.
  const Scene all = parse_obj("mem", obj, {{"lib.mtl", mtl}}, {.two_sided = true});
  ASSERT_EQ(all.triangles.size(), 4u);
  EXPECT_EQ(all.triangles[0].p, s.triangles[0].p);
  // A closed furnace made two-sided: its outsides face nothing either.
  EXPECT_EQ(load_scene("furnace", {.two_sided = true}).triangles.size(), builtin_furnace().triangles.size());

  try {
    parse_obj("mem", obj, {{"lib.mtl", "newmtl plain\nKd 0.5 0.5 0.5\nsirad_two_sided yes\nnewmtl glow\nKe 1 1 1\n"}});
    ADD_FAILURE() << "a bad sirad_two_sided was accepted";
  } catch (const Error& e) {
    expect_parts(e.what(), {"lib.mtl", "'plain'", "sirad_two_sided", "yes"});
  }
}


// Faces no light reaches are marked unlit (the mesher leaves them whole): in a closed room with a
// lamp, a roof over the ceiling facing up into nothing and a board outside facing the back of a
// wall; not a tile on the floor under a table, which no lamp lights directly but which sees the
// table's underside, lit by the floor.
TEST(SceneFile, FacesNoLightReachesAreMarked) {
  test::ObjBuilder o;
  test::room_shell(o);
  o.material("lamp");
  o.quad({1.5, 2.95, 1.5}, {2.5, 2.95, 1.5}, {2.5, 2.95, 2.5}, {1.5, 2.95, 2.5});
  o.material("panel");
  o.quad({1.0, 0.6, 1.0}, {1.0, 0.6, 3.0}, {3.0, 0.6, 3.0}, {3.0, 0.6, 1.0});  // the table's top, up
  o.quad({1.0, 0.58, 1.0}, {3.0, 0.58, 1.0}, {3.0, 0.58, 3.0}, {1.0, 0.58, 3.0});  // its underside, down
  o.material("rug");
  o.quad({1.8, 0.001, 1.8}, {1.8, 0.001, 2.2}, {2.2, 0.001, 2.2}, {2.2, 0.001, 1.8});  // the tile under it, up
  o.material("wall");
  o.quad({0, 3.2, 0}, {0, 3.2, 4}, {4, 3.2, 4}, {4, 3.2, 0});  // the roof, up
  o.wall_x(-1.0, 0, 3, 0, 4, true);                            // the board outside, towards the wall
  const Scene s = o.scene("marks", test::kMtl);
  // The floor is cut along the tile's outline and the ceiling along the lamp's back
  // (scene.h cut_along_gaps): the roof and the board are found by where they are. The floor's
  // pieces under the tile, 1 mm below it, get light only through that slit: marked or not.
  std::size_t roof_and_board = 0;
  for (const Triangle& t : s.triangles) {
    const bool roof = t.p[0].y == 3.2f && t.p[1].y == 3.2f && t.p[2].y == 3.2f;
    const bool board = t.p[0].x == -1.0f && t.p[1].x == -1.0f && t.p[2].x == -1.0f;
    const bool under_tile = t.in_gap && t.p[0].y == 0.0f && t.p[1].y == 0.0f && t.p[2].y == 0.0f;
    if (!under_tile) EXPECT_EQ(t.unlit, roof || board) << "a triangle at " << t.p[0].x << " " << t.p[0].y << " " << t.p[0].z;
    roof_and_board += roof || board;
  }
  EXPECT_EQ(roof_and_board, 4u);
}

TEST(SceneErrors, FilesThatAreNotScenes) {
  TempDir dir;
  expect_parts(error_of([&] { load_scene(dir.path("missing.obj")); }),
               {"missing.obj: no such file"});
  fs::create_directory(dir.path("folder.obj"));
  expect_parts(error_of([&] { load_scene(dir.path("folder.obj")); }),
               {"folder.obj: is a directory"});
  const std::string empty = dir.write("empty.obj", "");
  expect_parts(error_of([&] { load_scene(empty); }), {"empty.obj: scene has no triangles"});
  const std::string garbage = dir.write("garbage.obj", std::string("\x7f"
                                                                   "ELF\x02\x01\x01\0\0\xff\xfe",
                                                                   11));
  expect_parts(error_of([&] { load_scene(garbage); }), {"garbage.obj:1: binary data"});
  expect_parts(
      error_of([&] { load_scene(dir.path("model.fbx")); }),
      {"model.fbx: unsupported scene format (supported: .obj, .gltf, .glb, .ply; built-ins: cornell, furnace, bright-room, three-lights)"});
  expect_parts(error_of([&] { load_scene("cornel"); }), {"cornel: unsupported scene format"});
}

TEST(SceneErrors, BadGeometry) {
  TempDir dir;
  expect_parts(load_error(dir, kQuad + "f 1 2 99\n"),
               {"s.obj:9: face index 99 out of range (4 vertices)"});
  expect_parts(load_error(dir, kQuad + "f -1 -2 -5\n"),
               {"s.obj:9: face index -5 out of range (4 vertices)"});
  expect_parts(load_error(dir, kQuad + "f 1 2 99999999999999999999999\n"),
               {"s.obj:9: face index", "out of range"});
  expect_parts(load_error(dir, kQuad + "f 1 2 0\n"), {"s.obj:9: face index 0 is invalid"});
  expect_parts(load_error(dir, kQuad + "f 1 2\n"), {"s.obj:9: face has 2 vertices"});
  expect_parts(load_error(dir, kQuad + "f 1 2 x\n"), {"s.obj:9: bad face index 'x'"});
  expect_parts(load_error(dir, kQuad + "v nan 0 0\n"),
               {"s.obj:9: vertex has a non-finite coordinate"});
  expect_parts(load_error(dir, kQuad + "v 0 -inf 0\n"),
               {"s.obj:9: vertex has a non-finite coordinate"});
  expect_parts(load_error(dir, kQuad + "v 0 0 1e39\n"),
               {"s.obj:9: vertex coordinate '1e39' out of range"});
  expect_parts(load_error(dir, kQuad + "v 0 0\n"), {"s.obj:9: vertex needs 3 coordinates"});
  expect_parts(load_error(dir, kQuad + "v 0 zero 0\n"), {"s.obj:9: bad vertex coordinate 'zero'"});
}

TEST(SceneErrors, BadMaterials) {
  TempDir dir;
  expect_parts(load_error(dir, kQuad + "usemtl chrome\nf 1 2 3\n"),
               {"s.obj:10: unknown material 'chrome'"});
  // A bad material that no face uses is not looked at.
  dir.write("s.mtl", kMtl + "newmtl red\nKd 1.3 0 0\n");
  EXPECT_NO_THROW(load_scene(dir.write("s.obj", kQuad)));
  expect_parts(
      load_error(dir, kQuad + "usemtl red\nf 1 2 3\n", kMtl + "newmtl red\nKd 0.5 1.3 0\n"),
      {"s.mtl: material 'red': Kd 1.3 outside [0, 1]"});
  expect_parts(load_error(dir, kQuad, "newmtl light\nKd 0.5 0.5 0.5\nKe 1 -1 1\n"),
               {"s.mtl: material 'light': Ke -1 is negative"});
  expect_parts(load_error(dir, kQuad, "newmtl light\nKe 1 1e99 1\n"),
               {"s.mtl:2: Ke: '1e99' is not a finite number"});  // beyond float range: refused where it is written
  expect_parts(load_error(dir, "mtllib none.mtl\n" + kQuad), {"none.mtl: no such file"});
  std::string dark = kQuad;
  dark.replace(dark.find("usemtl light"), 12, "usemtl white");
  expect_parts(load_error(dir, dark), {"s.obj: scene has no emitter (no material with Ke > 0)"});
}

TEST(SceneErrors, DegenerateTriangles) {
  TempDir dir;
  const std::string obj = kQuad + "v 2 0 0\nf 1 2 5\nf 1 1 2\n";
  expect_parts(load_error(dir, obj), {"s.obj:10: degenerate triangle (zero area)"});
  // Accepted with skip_degenerate: both dropped, the quad stays.
  dir.write("s.mtl", kMtl);
  ImportOptions skip;
  skip.skip_degenerate = true;
  EXPECT_EQ(load_scene(dir.write("s.obj", obj), skip).triangles.size(), 2u);
  // Only degenerate triangles: nothing left.
  expect_parts(load_error(dir, "mtllib s.mtl\nusemtl light\nv 0 0 0\nv 1 1 1\nv 2 2 2\nf 1 2 3\n",
                          kMtl, skip),
               {"s.obj: scene has no triangles (1 skipped as degenerate)"});
}

// camera_spec writes what parse_camera reads (the form of --camera and the EXR's sirad.camera).
TEST(SceneFile, CameraSpecRoundTrips) {
  Camera c = *builtin_cornell().camera;
  Camera back = parse_camera(camera_spec(c));
  EXPECT_EQ(back.eye, c.eye);
  EXPECT_EQ(back.look_at, c.look_at);
  EXPECT_EQ(back.up, c.up);
  EXPECT_EQ(back.vfov_deg, c.vfov_deg);
}

TEST(SceneErrors, MalformedCameraLine) {
  TempDir dir;
  const std::string ok = "eye 0 0 5 look 0 0 0 up 0 1 0 fov 40";
  EXPECT_NO_THROW(parse_obj("c.obj", "# sirad camera " + ok + "\n" + kQuad, {{"s.mtl", kMtl}}));
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"eye 0 0 5 look 0 0 0 up 0 1 0", "missing 'fov'"},
      {"eye 0 0 5 look 0 0 0 up 0 1 0 fov", "'fov' needs 1 number"},
      {"eye 0 0 5 look 0 0 0 up 0 1 0 fov 40 eye 1 1 1", "'eye' given twice"},
      {"eye 0 0 5 look 0 0 0 up 0 1 0 fov 40 zoom 2", "unknown keyword 'zoom'"},
      {"eye 0 0 nan look 0 0 0 up 0 1 0 fov 40", "'eye' has a bad number 'nan'"},
      {"eye 0 0 5 look 0 0 0 up 0 0 1 fov 40", "up is zero or parallel to the view direction"},
      {"eye 0 0 5 look 0 0 5 up 0 1 0 fov 40", "eye and look are the same point"},
      {"eye 0 0 5 look 0 0 0 up 0 1 0 fov 180", "fov 180 outside (0, 180)"},
  };
  for (const auto& [line, why] : bad)
    expect_parts(load_error(dir, kQuad + "# sirad camera " + line + "\n"),
                 {"s.obj:9: malformed '# sirad camera' line: " + why});
  expect_parts(load_error(dir, "# sirad camera " + ok + "\n# sirad camera " + ok + "\n" + kQuad),
               {"s.obj:2: malformed '# sirad camera' line: a second camera line"});
}

// Hostile input never crashes or hangs: random bytes and random edits of a valid scene either
// load or throw sirad::Error.
TEST(SceneErrors, FuzzedInputOnlyThrowsSiradErrors) {
  std::mt19937_64 rng(12345);
  const std::string base = std::string(resource("scenes/cornell_box.obj"));
  const std::string mtl = std::string(resource("scenes/cornell_box.mtl"));
  const std::vector<std::string> words = {
      "nan", "-inf", "1e999",          "0",      "-99999", "99999999999", "",
      "f",   "v",    "usemtl",         "mtllib", "#",      "\r",          "\n",
      "/",   "-1",   "# sirad camera", "\x01",   "\xff",   "4294967297",  "+"};
  int loaded = 0;
  for (int round = 0; round < 3000; ++round) {
    std::string obj;
    if (round % 3 == 0) {
      obj.resize(rng() % 300);
      for (char& c : obj)
        c = static_cast<char>(rng() % 3 == 0 ? rng() % 256 : " vf0123456789-/\n."[rng() % 17]);
    } else {
      obj = base;
      for (int edits = 1 + rng() % 4; edits > 0; --edits) {
        const std::size_t at = rng() % obj.size();
        obj.replace(at, rng() % 6, words[rng() % words.size()]);
      }
    }
    try {
      parse_obj("fuzz.obj", obj, {{"cornell_box.mtl", mtl}});
      ++loaded;
    } catch (const Error&) {
    }
  }
  EXPECT_GT(loaded, 0);
}

}  // namespace
}  // namespace sirad

namespace sirad {
namespace {

// MTL values are read as strictly as OBJ's: one number means g = b = r (the MTL convention);
// a value that is not a finite number, a count other than 1 or 3, or a spectral or xyz colour
// is an error naming the file and line, never a silent 0 (tinyobjloader made `Kd 0.5` (0.5, 0,
// 0) and `Ke abc` 0).
TEST(SceneMtl, ValuesAreReadStrictly) {
  const std::string obj = "mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n";
  const Scene s = parse_obj("mem", obj, {{"lib.mtl", "# a comment\nnewmtl m # trailing\nKd 0.5\r\nKe 2 # bright\n"}});
  ASSERT_EQ(s.materials.size(), 1u);
  EXPECT_EQ(s.materials[0].reflectance, glm::vec3(0.5f));
  EXPECT_EQ(s.materials[0].emission, glm::vec3(2.0f));
  for (const auto& [mtl, parts] : std::vector<std::pair<std::string, std::vector<std::string>>>{
           {"newmtl m\nKd 0.5 0.5 0.5\nKe nan\n", {"lib.mtl:3:", "Ke", "'nan'", "not a finite number"}},
           {"newmtl m\nKd 0.5 0.5 0.5\nKe inf 1 1\n", {"lib.mtl:3:", "'inf'"}},
           {"newmtl m\nKd 0.5 0.5 0.5\nKe abc\n", {"lib.mtl:3:", "'abc'"}},
           {"newmtl m\nKd 0.5 0.5 0.5\nKe NaN NaN NaN\n", {"lib.mtl:3:", "'NaN'"}},
           {"newmtl m\nKd 0.5 0.5\nKe 1\n", {"lib.mtl:2:", "Kd takes 1 or 3 numbers (got 2)"}},
           {"newmtl m\nKd xyz 0.5 0.5 0.5\nKe 1\n", {"lib.mtl:2:", "only RGB"}},
           {"newmtl m\nKd 1e39 0 0\nKe 1\n", {"lib.mtl:2:", "'1e39'"}},
           {"newmtl\nKd 0.5\n", {"lib.mtl:1:", "newmtl without a name"}}})
    expect_parts(error_of([&] { parse_obj("mem", obj, {{"lib.mtl", mtl}}); }), parts);
}

}  // namespace
}  // namespace sirad
