// sirad tests: glTF 2.0 scenes (scene/gltf.h). A scene exported by Blender 3.4's own
// exporters (tests/data/blender/make_room.py wrote room.glb and room.obj + room.mtl): objects,
// materials with emission strength, two-sided materials, the transform hierarchy and the camera
// are read; the same scene as OBJ and as glTF gives the same answer; hostile files give one
// clear error and never a crash.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <set>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <fcntl.h>
#include <png.h>
#include <sys/inotify.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include <tiny_gltf.h>

#include "cli/run_flags.h"
#include "io/read_solution.h"
#include "io/write.h"
#include "io/write_gltf.h"
#include "render/gather.h"
#include "scene/gltf.h"
#include "scene/import.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "solver/reference.h"
#include "tests/coincident_scenes.h"
#include "tests/scene_files.h"
#include "tests/test_folder.h"
#include "util/error.h"
#include "util/json_bounded.h"

namespace sirad {
namespace {

namespace fs = std::filesystem;

const std::string kData = std::string(SIRAD_SOURCE_DIR) + "/tests/data/blender/";

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Blender's room (Blender is Z-up; its exporter writes glTF's Y-up: (x, y, z) -> (x, z, -y)).
TEST(Gltf, BlenderExportReadsObjectsMaterialsCameraAndTransforms) {
  Scene s = load_scene(kData + "room.glb");
  std::map<std::string, std::size_t> triangles;  // per object
  for (const Triangle& t : s.triangles) ++triangles[s.objects.at(t.object)];
  // Cube 12 triangles, plane 2, block 12; every material is doubleSided (Blender's default):
  // each triangle has its reversed twin where that side sees light. The room is the default cube
  // scaled up (normals out): its twins face in and are all kept, as are the lamp's; the block's
  // twins would face into the solid block and are not made.
  // The room's ceiling is cut along the lamp's outline 5 cm below it (scene/gap_cuts.cpp), and
  // both it and the lamp's upper side along strips by the rim: more triangles, the same areas
  // (the room's twice the cube's with the twins, the lamp's its two sides).
  std::map<std::string, double> area;
  for (const Triangle& t : s.triangles)
    area[s.objects.at(t.object)] += 0.5 * glm::length(glm::cross(glm::dvec3(t.p[1] - t.p[0]), glm::dvec3(t.p[2] - t.p[0])));
  EXPECT_GT(triangles["Room"], 24u);
  EXPECT_NEAR(area["Room"], 2.0 * (2 * 4.0 * 4.0 + 4 * 4.0 * 3.0), 1e-3);
  EXPECT_GT(triangles["Lamp"], 4u);
  EXPECT_NEAR(area["Lamp"], 2.0 * 1.0 * 1.0, 1e-5);
  EXPECT_EQ(triangles["Block"], 12u);
  std::map<std::string, Material> materials;
  for (const Material& m : s.materials) materials[m.name] = m;
  ASSERT_EQ(materials.count("LampGlow"), 1u);
  // Emission colour (1, 0.95, 0.9) times KHR_materials_emissive_strength 6.
  EXPECT_NEAR(materials["LampGlow"].emission.x, 6.0f, 1e-5f);
  EXPECT_NEAR(materials["LampGlow"].emission.y, 5.7f, 1e-5f);
  EXPECT_NEAR(materials["LampGlow"].emission.z, 5.4f, 1e-5f);
  EXPECT_NEAR(materials["Plaster"].reflectance.x, 0.7f, 1e-6f);
  EXPECT_NEAR(materials["Red"].reflectance.y, 0.2f, 1e-6f);
  for (const auto& [name, m] : materials) EXPECT_TRUE(m.two_sided) << name;
  // The camera: Blender's (-1.7, 1.7, 1.6) is glTF's (-1.7, 1.6, -1.7), vertical fov 60 degrees,
  // looking at the block.
  ASSERT_TRUE(s.camera.has_value());
  EXPECT_NEAR(s.camera->eye.x, -1.7f, 1e-5f);
  EXPECT_NEAR(s.camera->eye.y, 1.6f, 1e-5f);
  EXPECT_NEAR(s.camera->eye.z, -1.7f, 1e-5f);
  EXPECT_NEAR(s.camera->vfov_deg, 60.0f, 1e-3f);
  // The block under the pivot: centred at Blender's (0.6, -0.4, 0.5) = glTF (0.6, 0.5, 0.4),
  // turned 30 degrees about the vertical, so its x extent is 0.5 (cos 30 + sin 30) = 0.683.
  glm::vec3 lo(1e9f), hi(-1e9f);
  for (const Triangle& t : s.triangles)
    if (s.objects.at(t.object) == "Block")
      for (const glm::vec3& p : t.p) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
      }
  EXPECT_NEAR(0.5f * (lo.x + hi.x), 0.6f, 1e-5f);
  EXPECT_NEAR(0.5f * (lo.y + hi.y), 0.5f, 1e-5f);
  EXPECT_NEAR(0.5f * (lo.z + hi.z), 0.4f, 1e-5f);
  EXPECT_NEAR(0.5f * (hi.x - lo.x), 0.5f * (std::cos(0.5236f) + std::sin(0.5236f)), 1e-4f);
  EXPECT_NEAR(hi.y - lo.y, 1.0f, 1e-5f);
}

// The same Blender scene as OBJ (Blender's OBJ exporter: the same geometry, Ke = emission x
// strength; OBJ has no two-sidedness, so --two-sided stands for glTF's doubleSided) and as glTF
// meshes to the same areas per object and solves to the same radiosity per object: the
// reference solver on each, compared within 3 SE (SE of an object's mean at most the mean of its
// patches' SEs: full correlation), and within 0.5 % where that is the larger.
TEST(Gltf, TheSameSceneAsObjAndAsGltfGivesTheSameAnswer) {
  Scene gltf = load_scene(kData + "room.glb");
  Scene obj = load_scene(kData + "room.obj", {.two_sided = true});
  std::map<std::string, std::pair<double, double>> mean[2], se[2];
  int k = 0;
  for (const Scene* s : {&gltf, &obj}) {
    PatchMesh mesh = mesh_scene(*s, {.target_patches = 1500});
    ReferenceSolution ref = solve_reference(mesh, {.rays_per_patch = 1024, .light_samples = 256, .batches = 8, .seed = 9});
    std::map<std::string, double> area, b, e;
    for (std::size_t j = 0; j < mesh.size(); ++j) {
      const std::string& name = s->objects.at(s->triangles.at(mesh.source_triangle[j]).object);
      area[name] += mesh.area[j];
      b[name] += mesh.area[j] * (ref.radiosity[j].x + ref.radiosity[j].y + ref.radiosity[j].z);
      e[name] += mesh.area[j] * (ref.radiosity_se[j].x + ref.radiosity_se[j].y + ref.radiosity_se[j].z);
    }
    for (const auto& [name, a] : area) {
      mean[k][name] = {b[name] / a, a};
      se[k][name] = {e[name] / a, 0.0};
    }
    ++k;
  }
  for (const char* name : {"Room", "Lamp", "Block"}) {
    SCOPED_TRACE(name);
    auto [bg, ag] = mean[0][name];
    auto [bo, ao] = mean[1][name];
    std::printf("%s: glTF %.5f, OBJ %.5f (SE %.5f, %.5f), area %.5f / %.5f\n", name, bg, bo, se[0][name].first,
                se[1][name].first, ag, ao);
    EXPECT_NEAR(ag, ao, 1e-4 * ag);
    EXPECT_NEAR(bg, bo, std::max(3.0 * std::hypot(se[0][name].first, se[1][name].first), 0.005 * bg));
  }
}

// The buffer of gltf_text: 3 float3 positions, then 3 uint16 indices (and 2 bytes of padding).
std::vector<unsigned char> triangle_buffer() {
  std::vector<unsigned char> bytes;
  auto put_f = [&](float v) {
    unsigned char b[4];
    std::memcpy(b, &v, 4);
    bytes.insert(bytes.end(), b, b + 4);
  };
  for (float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put_f(v);
  for (uint16_t i : {0, 1, 2}) {
    bytes.push_back(static_cast<unsigned char>(i & 0xff));
    bytes.push_back(static_cast<unsigned char>(i >> 8));
  }
  bytes.push_back(0);
  bytes.push_back(0);
  return bytes;
}

std::string base64(const std::vector<unsigned char>& bytes) {
  static const char* b64 = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string enc;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t n = bytes[i] << 16 | (i + 1 < bytes.size() ? bytes[i + 1] << 8 : 0) | (i + 2 < bytes.size() ? bytes[i + 2] : 0);
    enc += b64[(n >> 18) & 63];
    enc += b64[(n >> 12) & 63];
    enc += i + 1 < bytes.size() ? b64[(n >> 6) & 63] : '=';
    enc += i + 2 < bytes.size() ? b64[n & 63] : '=';
  }
  return enc;
}

// A minimal glTF text around one buffer (base64), one accessor set and one material, with parts
// replaced by `edit` (key -> JSON text) to make it hostile.
std::string gltf_text(std::map<std::string, std::string> edit = {}) {
  const std::vector<unsigned char> bytes = triangle_buffer();
  const std::string enc = base64(bytes);
  std::map<std::string, std::string> part = {
      {"asset", R"({"version": "2.0"})"},
      {"scenes", R"([{"nodes": [0]}])"},
      {"nodes", R"([{"mesh": 0, "name": "Tri"}])"},
      {"meshes", R"([{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}])"},
      {"materials", R"([{"name": "Glow", "emissiveFactor": [1, 1, 1], "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1]}}])"},
      {"accessors", R"([{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]},
                        {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}])"},
      {"bufferViews", R"([{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}])"},
      {"buffers", fmt::format(R"([{{"byteLength": {}, "uri": "data:application/octet-stream;base64,{}"}}])", bytes.size(), enc)},
  };
  for (const auto& [key, value] : edit) part[key] = value;
  std::string out = "{";
  for (const auto& [key, value] : part) {
    if (value.empty()) continue;
    out += (out.size() > 1 ? ", \"" : "\"") + key + "\": " + value;
  }
  return out + "}";
}

class GltfFiles : public test::SceneFiles {};

TEST_F(GltfFiles, AMinimalFileLoads) {
  Scene s = load_scene(write("tri.gltf", gltf_text()));
  ASSERT_EQ(s.triangles.size(), 1u);
  EXPECT_EQ(s.objects.at(s.triangles[0].object), "Tri");
  EXPECT_EQ(s.materials[0].emission, glm::vec3(1.0f));
}

// The lightmap UV set (TEXCOORD_1) as each triangle's map: the node's transform applied to its
// corners, each corner maps to its UV; floats, or normalized unsigned shorts. A set that is not
// VEC2 or not one per vertex is refused, and one with no area is said in a warning.
TEST_F(GltfFiles, TheLightmapUvSetIsEachTrianglesMap) {
  const auto with_uv = [&](const std::vector<unsigned char>& bytes, int type, bool normalized, const std::string& kind, int count) {
    return gltf_text({
        {"nodes", R"([{"mesh": 0, "name": "Tri", "scale": [2, 3, 1], "translation": [1, 0, 0]}])"},
        {"meshes", R"([{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_1": 2}, "indices": 1, "material": 0}]}])"},
        {"accessors", fmt::format(R"([{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}},
                        {{"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}},
                        {{"bufferView": 2, "componentType": {}, "normalized": {}, "count": {}, "type": "{}"}}])",
                                  type, normalized ? "true" : "false", count, kind)},
        {"bufferViews", fmt::format(R"([{{"buffer": 0, "byteOffset": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 6}},
                          {{"buffer": 1, "byteOffset": 0, "byteLength": {}}}])", bytes.size())},
        {"buffers", fmt::format(R"([{{"byteLength": {}, "uri": "data:application/octet-stream;base64,{}"}},
                      {{"byteLength": {}, "uri": "data:application/octet-stream;base64,{}"}}])",
                                triangle_buffer().size(), base64(triangle_buffer()), bytes.size(), base64(bytes))},
    });
  };
  const std::array<glm::dvec2, 3> want = {glm::dvec2(0.25, 0.5), glm::dvec2(0.75, 0.5), glm::dvec2(0.25, 1.0)};
  std::vector<unsigned char> floats(24), shorts(12);
  for (std::size_t i = 0; i < 3; ++i)
    for (std::size_t k = 0; k < 2; ++k) {
      const float f = static_cast<float>(want[i][k]);
      std::memcpy(&floats[(i * 2 + k) * 4], &f, 4);
      const uint16_t u = static_cast<uint16_t>(std::lround(want[i][k] * 65535));
      shorts[(i * 2 + k) * 2] = static_cast<unsigned char>(u & 0xff), shorts[(i * 2 + k) * 2 + 1] = static_cast<unsigned char>(u >> 8);
    }
  for (const auto& [bytes, type, normalized] : {std::tuple{floats, 5126, false}, std::tuple{shorts, 5123, true}}) {
    const Scene s = load_scene(write("uv.gltf", with_uv(bytes, type, normalized, "VEC2", 3)));
    ASSERT_EQ(s.triangles.size(), 1u);
    const Triangle& t = s.triangles[0];
    EXPECT_EQ(t.p[1], glm::vec3(3, 0, 0));  // the node's transform
    ASSERT_LT(t.uv_map, s.uv_maps.size());
    const double step = type == 5126 ? 1e-6 : 1.0 / 65535;  // a short's quantum
    for (std::size_t k = 0; k < 3; ++k) {
      const glm::dvec2 uv = s.uv_maps[t.uv_map].at(glm::dvec3(t.p[k]));
      EXPECT_NEAR(uv.x, want[k].x, step) << type;
      EXPECT_NEAR(uv.y, want[k].y, step) << type;
    }
    // A point inside maps as the affine map of its corners does.
    const glm::dvec2 mid = s.uv_maps[t.uv_map].at((glm::dvec3(t.p[0]) + glm::dvec3(t.p[1]) + glm::dvec3(t.p[2])) / 3.0);
    EXPECT_NEAR(mid.x, (want[0].x + want[1].x + want[2].x) / 3, step);
    EXPECT_NEAR(mid.y, (want[0].y + want[1].y + want[2].y) / 3, step);
  }
  const auto refused = [&](const std::string& text) {
    try {
      load_scene(write("bad-uv.gltf", text));
      ADD_FAILURE() << "accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("bad-uv.gltf: node 0 'Tri' primitive 0: TEXCOORD_1 is not VEC2"), std::string::npos) << e.what();
    }
  };
  refused(with_uv(floats, 5126, false, "VEC3", 2));
  refused(with_uv(floats, 5126, false, "VEC2", 2));
  refused(with_uv(shorts, 5123, false, "VEC2", 3));  // unsigned shorts that are not normalized
  // The lightmap's size a baked glb names: read, or refused when it is no size.
  const std::string sized = with_uv(floats, 5126, false, "VEC2", 3);
  const auto with_asset = [&](const std::string& extras) {
    std::string text = sized;
    const std::string asset = R"("asset": {"version": "2.0"})";
    text.replace(text.find(asset), asset.size(), R"("asset": {"version": "2.0", "extras": {"sirad_lightmap": )" + extras + "}}");
    return text;
  };
  EXPECT_EQ(load_scene(write("sized.gltf", with_asset(R"({"width": 64, "height": 48})"))).lightmap_size, (std::array<int, 2>{64, 48}));
  EXPECT_FALSE(load_scene(write("unsized.gltf", sized)).lightmap_size.has_value());
  for (const char* bad : {R"({"width": 0, "height": 48})", R"({"width": 64.5, "height": 48})", R"({"width": 64, "height": 99999})"}) {
    try {
      load_scene(write("badsize.gltf", with_asset(bad)));
      ADD_FAILURE() << bad << ": accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("sirad_lightmap width and height are not whole numbers in 1..16384"), std::string::npos) << e.what();
    }
  }
  std::vector<unsigned char> flat(24, 0);
  const Scene s = load_scene(write("flat-uv.gltf", with_uv(flat, 5126, false, "VEC2", 3)));
  EXPECT_EQ(s.triangles[0].uv_map, kNoUvMap);
  ASSERT_FALSE(s.warnings.empty());
  EXPECT_NE(s.warnings.back().find("1 triangles have no area in TEXCOORD_1"), std::string::npos) << s.warnings.back();
}

// Every kind of bad file: one sirad::Error, one line, naming the file.
TEST_F(GltfFiles, HostileFilesGiveOneLineErrors) {
  const std::vector<std::pair<std::string, std::map<std::string, std::string>>> cases = {
      // Indices read as bytes from inside the float 1.0 (00 00 80 3f): 128, 63 and 0 of 3 vertices.
      {"index out of range", {{"accessors", R"([{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}, {"bufferView": 0, "byteOffset": 14, "componentType": 5121, "count": 3, "type": "SCALAR"}])"}}},
      {"accessor past its view", {{"accessors", R"([{"bufferView": 0, "componentType": 5126, "count": 300, "type": "VEC3"}, {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}])"}}},
      {"view past its buffer", {{"bufferViews", R"([{"buffer": 0, "byteOffset": 30, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}])"}}},
      {"no emitter", {{"materials", R"([{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1]}}])"}}},
      {"base colour above 1", {{"materials", R"([{"emissiveFactor": [1, 1, 1], "pbrMetallicRoughness": {"baseColorFactor": [1.5, 0.5, 0.5, 1]}}])"}}},
      {"negative emission", {{"materials", R"([{"emissiveFactor": [1, 1, 1], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": -2}}}])"}}},
      {"lines", {{"meshes", R"([{"primitives": [{"attributes": {"POSITION": 0}, "mode": 1, "material": 0}]}])"}}},
      {"no position", {{"meshes", R"([{"primitives": [{"attributes": {}, "material": 0}]}])"}}},
      {"node cycle", {{"nodes", R"([{"mesh": 0, "children": [1]}, {"children": [0]}])"}}},
      {"node missing", {{"scenes", R"([{"nodes": [7]}])"}}},
      {"infinite matrix", {{"nodes", R"([{"mesh": 0, "matrix": [1e308,0,0,0, 0,1e308,0,0, 0,0,1,0, 0,0,0,1], "scale": []}])"}}},
      {"punctual light", {{"extensionsUsed", R"(["KHR_lights_punctual"])"}, {"extensions", R"({"KHR_lights_punctual": {"lights": [{"type": "point"}]}})"}}},
      {"required extension", {{"extensionsRequired", R"(["EXT_meshopt_compression"])"}, {"extensionsUsed", R"(["EXT_meshopt_compression"])"}}},
      {"buffer from a device", {{"buffers", R"([{"byteLength": 48, "uri": "/dev/zero"}])"}}},
      {"missing buffer file", {{"buffers", R"([{"byteLength": 48, "uri": "nothere.bin"}])"}}},
      {"not json", {{"asset", "{{{"}}},
  };
  for (const auto& [what, edit] : cases) {
    SCOPED_TRACE(what);
    const std::string m = expect_refused("bad.gltf", gltf_text(edit));
    if (what == "index out of range") {
      EXPECT_NE(m.find("index 128 out of range"), std::string::npos) << m;
    }
  }
  for (const char* garbage : {"", "glTF", "glTF\x02\x00\x00\x00\xff\xff\xff\xff"}) {
    const std::string path = write("bad.glb", garbage);
    EXPECT_THROW(load_scene(path), Error);
  }
}

// A .glb holding `json` as its JSON chunk (padded with spaces) and no binary chunk.
std::string glb_of(std::string json) {
  while (json.size() % 4 != 0) json += ' ';
  std::string out = "glTF";
  auto put = [&](std::size_t v) {
    for (int k = 0; k < 4; ++k) out += static_cast<char>((v >> (8 * k)) & 0xff);
  };
  put(2);
  put(12 + 8 + json.size());
  put(json.size());
  out += "JSON";
  return out + json;
}

// JSON 200,000 levels deep in a node's extras (tinygltf converts extras recursively: it overflowed
// the stack) is refused before tinygltf parses it, in a .gltf and in a .glb's JSON chunk; the
// bound is the file's whole nesting (the node's extras sit at level 3); brackets inside a
// string, after an escaped quote, are not nesting.
TEST_F(GltfFiles, JsonNestedTooDeepIsRefusedBeforeItIsParsed) {
  auto with_extras = [](std::size_t depth) {
    return gltf_text({{"nodes", R"([{"mesh": 0, "extras": )" + std::string(depth, '[') + std::string(depth, ']') + "}]"}});
  };
  const std::string deep = with_extras(200000);
  for (const auto& [name, text] : {std::pair{"deep.gltf", deep}, std::pair{"deep.glb", glb_of(deep)}}) {
    const std::string m = expect_refused(name, text);
    EXPECT_NE(m.find(fmt::format("JSON nested deeper than {} levels", kMaxJsonDepth)), std::string::npos) << m;
  }
  EXPECT_EQ(load_scene(write("limit.gltf", with_extras(kMaxJsonDepth - 3))).triangles.size(), 1u);
  EXPECT_NE(expect_refused("past.gltf", with_extras(kMaxJsonDepth - 2)).find("nested deeper"), std::string::npos);
  const std::string brackets = R"(\")" + std::string(1000, '[') + "{";
  const Scene s = load_scene(write("name.glb", glb_of(gltf_text({{"nodes", R"([{"mesh": 0, "name": ")" + brackets + R"("}])"}}))));
  EXPECT_EQ(s.objects.at(s.triangles.at(0).object).substr(0, 3), "\"[[");
}

// A buffer or an image whose URI names a FIFO is refused without being opened (tinygltf's own
// FileExists opened it: an open of a FIFO with no writer blocks for ever). The test holds both
// ends open, so that an importer that opens it cannot hang, and watches the FIFO with inotify:
// nothing else opens it.
TEST_F(GltfFiles, AFifoAsABufferOrAnImageIsRefusedWithoutBeingOpened) {
  const fs::path fifo = dir_ / "pipe.bin";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
  const int reader = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  const int writer = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
  const int watch = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  ASSERT_GE(reader, 0);
  ASSERT_GE(writer, 0);
  ASSERT_GE(watch, 0);
  ASSERT_GE(::inotify_add_watch(watch, fifo.c_str(), IN_OPEN), 0);
  const std::string textured = R"([{"emissiveFactor": [1, 1, 1], "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}])";
  const std::vector<std::map<std::string, std::string>> cases = {
      {{"buffers", R"([{"byteLength": 48, "uri": "pipe.bin"}])"}},
      {{"images", R"([{"uri": "pipe.bin"}])"}, {"textures", R"([{"source": 0}])"}, {"materials", textured}}};
  for (const auto& edit : cases) {
    const std::string m = expect_refused("fifo.gltf", gltf_text(edit));
    EXPECT_NE(m.find("URI 'pipe.bin' is not a regular file"), std::string::npos) << m;
  }
  alignas(inotify_event) char events[4096];
  EXPECT_LT(::read(watch, events, sizeof events), 0) << "the FIFO was opened";
  ::close(watch);
  ::close(writer);
  ::close(reader);
}

// External buffers are read from the scene's folder only: `../` (also percent-encoded), a
// symlink that leads out, an absolute path and a URI with a scheme are refused, though each names
// a valid buffer; a subfolder and a symlink within the folder are read.
TEST_F(GltfFiles, ExternalUrisStayInTheScenesFolder) {
  const std::vector<unsigned char> bytes = triangle_buffer();
  const std::string buffer(bytes.begin(), bytes.end());
  write("outside.bin", buffer);
  fs::create_directories(dir_ / "scene" / "sub");
  write("scene/sub/inside.bin", buffer);
  fs::create_symlink(dir_ / "outside.bin", dir_ / "scene" / "out_link.bin");
  fs::create_symlink("sub/inside.bin", dir_ / "scene" / "in_link.bin");
  auto with_uri = [&](const std::string& uri) {
    return gltf_text({{"buffers", fmt::format(R"([{{"byteLength": {}, "uri": "{}"}}])", bytes.size(), uri)}});
  };
  for (const std::string uri : {"sub/inside.bin", "in_link.bin", "sub/../in_link.bin"})
    EXPECT_EQ(load_scene(write("scene/ok.gltf", with_uri(uri))).triangles.size(), 1u) << uri;
  const std::vector<std::pair<std::string, std::string>> refused = {
      {"../outside.bin", "URI '../outside.bin' names a file outside the scene's folder"},
      {"sub/../../outside.bin", "outside the scene's folder"},
      {"%2E%2E/outside.bin", "outside the scene's folder"},
      {"out_link.bin", "outside the scene's folder"},
      {(dir_ / "outside.bin").string(), "is an absolute path"},
      {"file://" + (dir_ / "outside.bin").string(), "has a scheme"},
  };
  for (const auto& [uri, why] : refused) {
    const std::string m = expect_refused("scene/bad.gltf", with_uri(uri));
    EXPECT_NE(m.find(why), std::string::npos) << uri << ": " << m;
  }
  // --allow-outside-uris (ImportOptions::outside_uris): relative URIs may leave the folder; an
  // absolute path, a scheme and a file that is not regular are still refused.
  const ImportOptions outside{.outside_uris = true};
  for (const std::string uri : {"../outside.bin", "out_link.bin", "sub/../../outside.bin"})
    EXPECT_EQ(load_scene(write("scene/ok.gltf", with_uri(uri)), outside).triangles.size(), 1u) << uri;
  for (const std::string& uri : {(dir_ / "outside.bin").string(), "file://" + (dir_ / "outside.bin").string(), std::string("../scene")})
    EXPECT_THROW(load_scene(write("scene/bad.gltf", with_uri(uri)), outside), Error) << uri;
}

// One mesh of 4096 triangles used by enough nodes to make more than kMaxTriangles (a file of
// 80 KB): refused from the count, naming it, before a triangle is made; used by two nodes it is
// made twice.
TEST_F(GltfFiles, AMeshUsedByManyNodesIsCountedBeforeItIsMade) {
  constexpr std::size_t kPerMesh = 4096;
  std::vector<unsigned char> bytes = triangle_buffer();
  bytes.resize(36);  // the positions, then 3 x 4096 byte indices 0, 1, 2, ...
  for (std::size_t i = 0; i < 3 * kPerMesh; ++i) bytes.push_back(static_cast<unsigned char>(i % 3));
  auto used_by = [&](std::size_t nodes) {
    std::string node_list, roots;
    for (std::size_t k = 0; k < nodes; ++k) {
      node_list += std::string(k ? ", " : "") + R"({"mesh": 0})";
      roots += (k ? ", " : "") + std::to_string(k);
    }
    return gltf_text(
        {{"accessors", fmt::format(R"([{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0,0,0], "max": [1,1,0]}},
                                      {{"bufferView": 1, "componentType": 5121, "count": {}, "type": "SCALAR"}}])", 3 * kPerMesh)},
         {"bufferViews", fmt::format(R"([{{"buffer": 0, "byteOffset": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": {}}}])",
                                     3 * kPerMesh)},
         {"buffers", fmt::format(R"([{{"byteLength": {}, "uri": "data:application/octet-stream;base64,{}"}}])", bytes.size(), base64(bytes))},
         {"nodes", "[" + node_list + "]"},
         {"scenes", R"([{"nodes": [)" + roots + "]}]"}});
  };
  EXPECT_EQ(import_gltf(write("two.gltf", used_by(2)), {}).triangles.size(), 2 * kPerMesh);
  const std::size_t nodes = import::kMaxTriangles / kPerMesh + 1;
  const std::string path = write("many.gltf", used_by(nodes));
  try {
    import_gltf(path, {});
    ADD_FAILURE() << "accepted";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(fmt::format("{}: its node tree makes {} triangles", path, nodes * kPerMesh)), std::string::npos) << m;
  }
}

// An image's size is read from its header before it is decoded: a PNG of 8193 x 8192 (268 MB as
// RGBA) and a JPEG that says 20000 x 20000 are refused, naming the image and its size; a small
// texture is still decoded and counts by its mean colour.
TEST_F(GltfFiles, AnImageTooLargeIsRefusedFromItsHeader) {
  auto write_png = [&](const std::string& name, uint32_t width, uint32_t height, unsigned char grey) {
    png_image image;
    std::memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    image.width = width;
    image.height = height;
    image.format = PNG_FORMAT_GRAY;
    const std::vector<unsigned char> pixels(std::size_t{width} * height, grey);
    EXPECT_TRUE(png_image_write_to_file(&image, (dir_ / name).c_str(), 0, pixels.data(), 0, nullptr)) << image.message;
  };
  auto textured = [](const std::string& uri) {
    return gltf_text({{"images", R"([{"uri": ")" + uri + R"("}])"},
                      {"textures", R"([{"source": 0}])"},
                      {"materials", R"([{"emissiveFactor": [1, 1, 1], "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1], "baseColorTexture": {"index": 0}}}])"}});
  };
  write_png("small.png", 4, 4, 128);
  const Scene s = load_scene(write("small.gltf", textured("small.png")));
  EXPECT_NEAR(s.materials.at(s.triangles.at(0).material).reflectance.x, 0.5 * import::srgb_to_linear(128.0 / 255.0), 1e-6);
  write_png("big.png", 8193, 8192, 128);
  std::string m = expect_refused("big.gltf", textured("big.png"));
  EXPECT_NE(m.find("image 0 'big.png' is 8193 x 8192 pixels"), std::string::npos) << m;
  // SOI, a JFIF APP0, a baseline frame of 20000 x 20000 with three components, EOI.
  const std::string jpeg = std::string("\xff\xd8\xff\xe0\x00\x10JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00", 20) +
                           std::string("\xff\xc0\x00\x11\x08\x4e\x20\x4e\x20\x03\x01\x22\x00\x02\x11\x01\x03\x11\x01\xff\xd9", 21);
  write("big.jpg", jpeg);
  m = expect_refused("jpeg.gltf", textured("big.jpg"));
  EXPECT_NE(m.find("image 0 'big.jpg' is 20000 x 20000 pixels"), std::string::npos) << m;
}

// The two sides of a two-sided face come back from the glb apart, each pulled kSidesApart of the
// scene's radius along its own normal (io/write_gltf.h): Cycles, which ignores back-face
// culling, then shows the side that faces the camera instead of either at random. Here the lamp
// 1.5 cm under a ceiling, its lower side lit by itself and its upper side by the gap.
TEST_F(GltfFiles, TheTwoSidesOfAFaceComeBackApart) {
  const PatchMesh mesh = mesh_scene(test::lamp_under_ceiling(0.015), {.target_patches = 600});
  std::vector<glm::vec3> radiosity(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) radiosity[j] = mesh.emission(j) + glm::vec3(mesh.normal[j].y > 0 ? 2.0f : 0.1f);
  const std::string path = (dir_ / "lamp.glb").string();
  write_glb(path, mesh, radiosity, 0.0f, 1.0);
  const Solution back = read_solution(path);
  const double apart = kSidesApart * mesh.bound_radius;
  std::size_t up = 0, down = 0;
  for (std::size_t j = 0; j < back.mesh.size(); ++j) {
    if (!back.mesh.emits(j)) continue;
    for (uint32_t v : back.mesh.patches[j]) {
      const double y = back.mesh.vertices[v].y;
      if (back.mesh.normal[j].y > 0.5f) {
        EXPECT_NEAR(y, 2.985 + apart, 1e-6);
        ++up;
      } else {
        EXPECT_NEAR(y, 2.985 - apart, 1e-6);
        ++down;
      }
    }
  }
  EXPECT_GT(up, 0u);  // the upper side, cut into strips by its rim (scene/gap_cuts.cpp), has more corners
  EXPECT_GT(down, 0u);
  // The ceiling, a face of one side only, stays where it is.
  for (std::size_t j = 0; j < back.mesh.size(); ++j) {
    if (back.mesh.normal[j].y < -0.5f && !back.mesh.emits(j)) {
      for (uint32_t v : back.mesh.patches[j]) EXPECT_EQ(back.mesh.vertices[v].y, 3.0f);
    }
  }
}

// A solution read back from the .glb sirad wrote renders as from its PLY (io/read_solution.h): the
// same patches, the corner values the gather interpolates, the camera and background exactly,
// so the final gathers of the two are one image bit for bit; reflectance and emission come
// from the materials' extras (the base colour is an unlit white).
TEST_F(GltfFiles, ASolutionReadBackFromItsGlbRendersAsFromItsPly) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), MeshOptions{.target_patches = 300});
  mesh.background = glm::vec3(0.25f, 0.5f, 0.125f);
  mesh.camera->eye.x += 0.1234567f;  // a view no matrix rebuilds exactly
  std::vector<glm::vec3> radiosity(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j)
    radiosity[j] = mesh.emission(j) + mesh.reflectance(j) * (1.0f + 0.37f * static_cast<float>(j % 11));
  const std::string glb = (dir_ / "s.glb").string(), ply = (dir_ / "s.ply").string();
  write_glb(glb, mesh, radiosity, 0.0f, 1.0);
  write_ply(ply, mesh, radiosity, 0.0f);
  const Solution a = read_solution(glb), b = read_solution(ply);
  ASSERT_EQ(a.mesh.size(), mesh.size());
  ASSERT_EQ(b.mesh.size(), mesh.size());
  ASSERT_TRUE(a.mesh.camera && b.mesh.camera);
  EXPECT_EQ(camera_spec(*a.mesh.camera), camera_spec(*mesh.camera));
  EXPECT_EQ(a.mesh.background, mesh.background);
  for (std::size_t m = 0; m < a.mesh.materials.size(); ++m) {
    const Material& got = a.mesh.materials[m];
    const auto want = std::find_if(mesh.materials.begin(), mesh.materials.end(), [&](const Material& x) { return x.name == got.name; });
    ASSERT_NE(want, mesh.materials.end()) << got.name;
    EXPECT_EQ(got.reflectance, want->reflectance) << got.name;
    EXPECT_EQ(got.emission, want->emission) << got.name;
  }
  const GatherOptions o{.width = 20, .height = 16, .spp = 4, .seed = 3, .threads = 2};
  const GatherPasses from_glb = FinalGather(a.mesh, a.corners, o).render(*a.mesh.camera);
  const GatherPasses from_ply = FinalGather(b.mesh, b.corners, o).render(*b.mesh.camera);
  EXPECT_EQ(from_glb.combined.pixels, from_ply.combined.pixels);
  EXPECT_EQ(from_glb.direct.pixels, from_ply.direct.pixels);
  EXPECT_EQ(from_glb.indirect.pixels, from_ply.indirect.pixels);
  double sum = 0;
  for (const glm::vec3& v : from_glb.indirect.pixels) sum += v.x;
  EXPECT_GT(sum, 0.0) << "an image with light in it";
  // A glTF from elsewhere is a scene, not a solution; a solution's extras out of range refused.
  try {
    read_solution(write("tri.gltf", gltf_text()));
    ADD_FAILURE() << "a glTF without _RADIANCE read as a solution";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no _RADIANCE"), std::string::npos) << e.what();
  }
  const std::string m = expect_refused(
      "bad.gltf", gltf_text({{"materials", R"([{"emissiveFactor": [1, 1, 1], "extras": {"sirad_reflectance": [0.5, 2, 0.5]}}])"}}));
  EXPECT_NE(m.find("sirad_reflectance"), std::string::npos) << m;
  EXPECT_NE(expect_refused("bad.gltf", gltf_text({{"asset", R"({"version": "2.0", "extras": {"sirad_background": [1, -1, 0]}})"}}))
                .find("sirad_background"),
            std::string::npos);
  EXPECT_THROW(read_solution(write("s.txt", "x")), Error);
}

// Random damage to Blender's .glb (bytes flipped, cut short, spans overwritten): every load
// either succeeds or throws sirad::Error; nothing crashes and no other exception escapes.
TEST_F(GltfFiles, DamagedBinaryFilesOnlyThrowSiradErrors) {
  const std::string base = slurp(kData + "room.glb");
  ASSERT_GT(base.size(), 1000u);
  std::mt19937_64 rng(77);
  int loaded = 0;
  for (int round = 0; round < 400; ++round) {
    std::string g = base;
    switch (round % 3) {
      case 0:
        for (int k = 0; k < 1 + static_cast<int>(rng() % 8); ++k) g[rng() % g.size()] = static_cast<char>(rng());
        break;
      case 1:
        g.resize(rng() % g.size());
        break;
      default: {
        std::size_t at = rng() % g.size(), n = std::min<std::size_t>(rng() % 64, g.size() - at);
        for (std::size_t i = 0; i < n; ++i) g[at + i] = static_cast<char>("0123456789-e.,[]{}\"\xff"[rng() % 20]);
      }
    }
    const std::string path = write("damaged.glb", g);
    try {
      load_scene(path);
      ++loaded;
    } catch (const Error&) {
    }
  }
  std::printf("damaged .glb: %d of 400 still loaded\n", loaded);
}


// NAME.glb read back with tinygltf: a mesh per object of the input, named as in the OBJ; every
// patch a triangle at its own corners whose _RADIANCE is corner_radiosity's value exactly and
// whose COLOR_0 is that times 2^exposure clamped to [0, 1]; vertices shared within a smooth
// surface (fewer than 3 per patch) but split at creases and material borders (more than the
// welded vertices); unlit materials; the camera node.
TEST_F(GltfFiles, TheSolutionAsGlbReadsBack) {
  PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = 600});
  std::vector<glm::vec3> radiosity(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j)
    radiosity[j] = glm::vec3(0.2f + 0.001f * static_cast<float>(j % 500), 0.5f, 1.5f * static_cast<float>(j % 3));
  const std::string path = (dir_ / "cornell.glb").string();
  write_glb(path, mesh, radiosity, -1.0f, 1.5);
  tinygltf::TinyGLTF loader;
  tinygltf::Model m;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &err, &warn, path)) << err;
  std::set<std::string> names;
  for (const auto& g : m.meshes) names.insert(g.name);
  EXPECT_EQ(names, (std::set<std::string>{"floor", "ceiling", "light", "back_wall", "right_wall_green", "left_wall_red",
                                          "short_block", "tall_block"}));
  for (const auto& mat : m.materials) EXPECT_EQ(mat.extensions.count("KHR_materials_unlit"), 1u) << mat.name;
  ASSERT_EQ(m.cameras.size(), 1u);
  EXPECT_NEAR(m.cameras[0].perspective.aspectRatio, 1.5, 1e-12);
  const auto corners = corner_radiosity(mesh, radiosity);
  // Patches of each object and material, in patch order, as write_glb lays them out.
  std::map<std::string, std::map<uint32_t, std::vector<std::size_t>>> expect;
  for (std::size_t j = 0; j < mesh.size(); ++j)
    expect[mesh.objects[mesh.triangle_object[mesh.source_triangle[j]]]][mesh.material[j]].push_back(j);
  auto floats = [&](int accessor) {
    const auto& a = m.accessors[static_cast<std::size_t>(accessor)];
    const auto& v = m.bufferViews[static_cast<std::size_t>(a.bufferView)];
    std::vector<float> out(a.count * 3);
    std::memcpy(out.data(), m.buffers[0].data.data() + v.byteOffset + a.byteOffset, out.size() * 4);
    return out;
  };
  std::size_t vertices = 0, triangles = 0;
  for (const auto& g : m.meshes)
    for (const auto& prim : g.primitives) {
      const auto& patches = expect.at(g.name).at(static_cast<uint32_t>(prim.material));
      auto pos = floats(prim.attributes.at("POSITION")), col = floats(prim.attributes.at("COLOR_0")),
           rad = floats(prim.attributes.at("_RADIANCE"));
      const auto& ia = m.accessors[static_cast<std::size_t>(prim.indices)];
      ASSERT_EQ(ia.count, 3 * patches.size());
      std::vector<uint32_t> idx(ia.count);
      const auto& iv = m.bufferViews[static_cast<std::size_t>(ia.bufferView)];
      std::memcpy(idx.data(), m.buffers[0].data.data() + iv.byteOffset + ia.byteOffset, idx.size() * 4);
      vertices += pos.size() / 3;
      triangles += patches.size();
      for (std::size_t t = 0; t < patches.size(); ++t)
        for (int k = 0; k < 3; ++k) {
          const uint32_t v = idx[3 * t + static_cast<std::size_t>(k)];
          const std::size_t j = patches[t];
          for (int c = 0; c < 3; ++c) {
            ASSERT_EQ(pos[3 * v + static_cast<std::size_t>(c)], mesh.vertices[mesh.patches[j][static_cast<std::size_t>(k)]][c]);
            ASSERT_EQ(rad[3 * v + static_cast<std::size_t>(c)], corners[j][static_cast<std::size_t>(k)][c]);
            ASSERT_EQ(col[3 * v + static_cast<std::size_t>(c)], std::clamp(corners[j][static_cast<std::size_t>(k)][c] * 0.5f, 0.0f, 1.0f));
          }
        }
    }
  EXPECT_EQ(triangles, mesh.size());
  EXPECT_LT(vertices, 3 * mesh.size()) << "no vertex is shared";
  EXPECT_GT(vertices, mesh.vertices.size()) << "creases and material borders are not split";
}

// The Khronos glTF validator (npm gltf-validator; .ci/run installs it and sets
// SIRAD_GLTF_VALIDATOR to its node_modules folder) finds no error and no warning in a `sirad
// render` .glb of the Cornell box. Skipped where it is not installed.
TEST_F(GltfFiles, RenderedGlbPassesTheKhronosValidator) {
  const char* modules = std::getenv("SIRAD_GLTF_VALIDATOR");
  if (modules == nullptr || !fs::exists(fs::path(modules) / "gltf-validator"))
    GTEST_SKIP() << "gltf-validator not installed (SIRAD_GLTF_VALIDATOR=.../node_modules)";
  const std::string out = (dir_ / "c").string();
  std::string cmd = fmt::format("'{}' render cornell --patches 500 --bundles 16 --width 16 --height 16 --out '{}' -q > /dev/null",
                                SIRAD_BINARY, out);
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::ofstream(dir_ / "validate.js")
      << "const v = require('gltf-validator'); const fs = require('fs');\n"
         "v.validateBytes(new Uint8Array(fs.readFileSync(process.argv[2]))).then((r) => {\n"
         "  console.log(JSON.stringify(r.issues));\n"
         "  process.exit(r.issues.numErrors + r.issues.numWarnings > 0 ? 1 : 0);\n"
         "}, (e) => { console.log(String(e)); process.exit(2); });\n";
  const std::string report = (dir_ / "report.txt").string();
  cmd = fmt::format("NODE_PATH='{}' node '{}' '{}.glb' > '{}' 2>&1", modules, (dir_ / "validate.js").string(), out, report);
  int rc = std::system(cmd.c_str());
  EXPECT_EQ(rc, 0) << slurp(report);
  std::printf("gltf-validator: %s\n", slurp(report).c_str());
}

}  // namespace
}  // namespace sirad
