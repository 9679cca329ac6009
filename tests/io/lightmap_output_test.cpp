// sirad tests: a baked lightmap's files (io/write_lightmap.h) read back: the half-float EXR
// with its layers, the glb's faces at their atlas UV in TEXCOORD_0 and TEXCOORD_1, its unlit
// materials showing the embedded PNG, the two sides of a two-sided face apart, and the refusals.
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include <Imath/half.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include "io/write_gltf.h"
#include "io/write_lightmap.h"
#include "scene/gltf.h"
#include "scene/atlas.h"
#include "tests/quad_scene.h"
#include "util/error.h"

namespace sirad {
namespace {

class LightmapFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("sirad-lightmap-" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

// A floor and, standing on it, a two-sided panel (a zero-thickness wall: the panel and its
// reversed twin), and a lamp; a lightmap whose every texel holds values of its own position.
struct Baked {
  test::QuadScene q;
  Atlas atlas;
  Lightmap map;
  Baked() {
    const uint32_t grey = q.material(glm::vec3(0.5f), glm::vec3(0.0f));
    const uint32_t panel = q.material(glm::vec3(0.7f, 0.6f, 0.5f), glm::vec3(0.0f));
    q.scene.materials[panel].two_sided = true;
    const uint32_t lamp = q.material(glm::vec3(0.0f), glm::vec3(3.0f));
    q.scene.objects = {"floor", "panel", "lamp"};
    q.quad({-2, -2, 0}, {2, -2, 0}, {2, 2, 0}, {-2, 2, 0}, grey);
    q.quad({0, -1, 0}, {0, 1, 0}, {0, 1, 1}, {0, -1, 1}, panel);
    q.quad({0, -1, 0}, {0, -1, 1}, {0, 1, 1}, {0, 1, 0}, panel);  // its back
    q.quad({-0.5f, -0.5f, 2}, {-0.5f, 0.5f, 2}, {0.5f, 0.5f, 2}, {0.5f, -0.5f, 2}, lamp);
    for (std::size_t t = 0; t < q.scene.triangles.size(); ++t) q.scene.triangles[t].object = t < 2 ? 0 : t < 6 ? 1 : 2;
    atlas = make_atlas(q.scene, {.texel_size = 0.25, .gutter = 1});
    for (Image* image : {&map.direct, &map.indirect, &map.combined, &map.error}) {
      image->width = atlas.width, image->height = atlas.height;
      image->pixels.assign(static_cast<std::size_t>(atlas.width) * atlas.height, glm::vec3(0.0f));
    }
    map.coverage.assign(map.combined.pixels.size(), 1.0f);
    for (std::size_t i = 0; i < map.coverage.size(); i += 3) map.coverage[i] = 0.25f * static_cast<float>(i % 5);
    for (int y = 0; y < atlas.height; ++y)
      for (int x = 0; x < atlas.width; ++x) {
        map.direct.at(x, y) = glm::vec3(0.01f * x, 0.02f * y, 0.5f);
        map.indirect.at(x, y) = glm::vec3(0.001f * y, 0.003f * x, 0.25f);
        map.combined.at(x, y) = map.direct.at(x, y) + map.indirect.at(x, y);
        map.error.at(x, y) = glm::vec3(0.001f * (x + y));
      }
  }
};

TEST_F(LightmapFiles, TheExrHoldsEachLayerAsHalfFloats) {
  Baked b;
  const std::string name = (dir_ / "scene").string();
  const auto files = write_lightmap(name, b.q.scene, b.atlas, b.map, 0.0f, nullptr, 1.5, {{"sirad.test", int64_t{7}}});
  EXPECT_EQ(files.exr, name + "-lightmap.exr");
  EXPECT_TRUE(std::filesystem::is_regular_file(files.png));
  Image coverage;  // the share of each texel's samples kept, in all three channels
  coverage.width = b.atlas.width, coverage.height = b.atlas.height;
  for (std::size_t i = 0; i < b.map.coverage.size(); ++i) coverage.pixels.emplace_back(b.map.coverage[i]);
  Imf::InputFile in(files.exr.c_str());
  const auto dw = in.header().dataWindow();
  ASSERT_EQ(dw.max.x - dw.min.x + 1, b.atlas.width);
  ASSERT_EQ(dw.max.y - dw.min.y + 1, b.atlas.height);
  const std::vector<std::pair<std::string, const Image*>> layers = {
      {"", &b.map.combined}, {"direct.", &b.map.direct}, {"indirect.", &b.map.indirect}, {"error.", &b.map.error}, {"coverage.", &coverage}};
  Imf::FrameBuffer frame;
  std::vector<std::vector<float>> got(layers.size() * 3, std::vector<float>(b.map.combined.pixels.size()));
  for (std::size_t l = 0; l < layers.size(); ++l)
    for (int c = 0; c < 3; ++c) {
      const std::string channel = layers[l].first + "RGB"[c];
      const Imf::Channel* info = in.header().channels().findChannel(channel);
      ASSERT_NE(info, nullptr) << channel;
      EXPECT_EQ(info->type, Imf::HALF) << channel;
      frame.insert(channel, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(got[3 * l + static_cast<std::size_t>(c)].data()),
                                       sizeof(float), sizeof(float) * static_cast<std::size_t>(b.atlas.width)));
    }
  in.setFrameBuffer(frame);
  in.readPixels(dw.min.y, dw.max.y);
  for (std::size_t l = 0; l < layers.size(); ++l)
    for (std::size_t i = 0; i < b.map.combined.pixels.size(); ++i)
      for (int c = 0; c < 3; ++c)  // each value as half rounds it, exactly
        ASSERT_EQ(got[3 * l + static_cast<std::size_t>(c)][i], float(Imath::half(layers[l].second->pixels[i][c]))) << l << " " << i;
}

// The glb read back: every scene triangle once, at its own corners (the two-sided panel's
// sides pulled apart along their normals), with its atlas UV in both TEXCOORD_0 and
// TEXCOORD_1; unlit materials whose base colour is texture 0, the embedded PNG; the asset's
// extras naming the EXR; the camera.
TEST_F(LightmapFiles, TheGlbCarriesTheAtlasUvAndShowsTheLightmap) {
  Baked b;
  const std::string name = (dir_ / "scene").string();
  const Camera camera{{0, -3, 1}, {0, 0, 0.5f}, {0, 0, 1}, 50};
  const auto files = write_lightmap(name, b.q.scene, b.atlas, b.map, -1.0f, &camera, 1.5, {});
  tinygltf::TinyGLTF loader;
  tinygltf::Model m;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &err, &warn, files.glb)) << err;
  EXPECT_EQ(m.asset.extras.Get("sirad_lightmap").Get("exr").Get<std::string>(), "scene-lightmap.exr");
  ASSERT_EQ(m.images.size(), 1u);
  EXPECT_EQ(m.images[0].mimeType, "image/png");
  const tinygltf::BufferView& view = m.bufferViews.at(static_cast<std::size_t>(m.images[0].bufferView));
  const std::vector<unsigned char> png = png_bytes("x", b.map.combined, -1.0f);
  ASSERT_EQ(view.byteLength, png.size());
  EXPECT_TRUE(std::equal(png.begin(), png.end(), m.buffers[0].data.begin() + static_cast<std::ptrdiff_t>(view.byteOffset)));
  ASSERT_EQ(m.materials.size(), b.q.scene.materials.size());
  for (const auto& mat : m.materials) {
    EXPECT_EQ(mat.extensions.count("KHR_materials_unlit"), 1u);
    EXPECT_EQ(mat.pbrMetallicRoughness.baseColorTexture.index, 0);
    EXPECT_EQ(mat.pbrMetallicRoughness.baseColorTexture.texCoord, 0);
    EXPECT_FALSE(mat.doubleSided);
  }
  ASSERT_EQ(m.cameras.size(), 1u);
  EXPECT_NEAR(m.cameras[0].perspective.aspectRatio, 1.5, 1e-12);
  auto floats = [&](int accessor) {
    const tinygltf::Accessor& a = m.accessors.at(static_cast<std::size_t>(accessor));
    const tinygltf::BufferView& v = m.bufferViews.at(static_cast<std::size_t>(a.bufferView));
    const auto* p = reinterpret_cast<const float*>(m.buffers[0].data.data() + v.byteOffset + a.byteOffset);
    return std::vector<float>(p, p + a.count * static_cast<std::size_t>(tinygltf::GetNumComponentsInType(static_cast<uint32_t>(a.type))));
  };
  const double apart = kSidesApart * 0.5 * std::sqrt(4.0 * 4.0 + 4.0 * 4.0 + 2.0 * 2.0);  // the scene's radius
  std::vector<int> found(b.q.scene.triangles.size(), 0);
  for (const auto& mesh : m.meshes)
    for (const auto& prim : mesh.primitives) {
      ASSERT_EQ(prim.attributes.at("TEXCOORD_1"), prim.attributes.at("TEXCOORD_0"));
      const std::vector<float> pos = floats(prim.attributes.at("POSITION")), uv = floats(prim.attributes.at("TEXCOORD_1"));
      const tinygltf::Accessor& ia = m.accessors.at(static_cast<std::size_t>(prim.indices));
      const tinygltf::BufferView& iv = m.bufferViews.at(static_cast<std::size_t>(ia.bufferView));
      const auto* index = reinterpret_cast<const uint32_t*>(m.buffers[0].data.data() + iv.byteOffset);
      for (std::size_t k = 0; k + 2 < ia.count; k += 3) {
        // The scene triangle of this material whose UV these are, at its corners.
        bool matched = false;
        for (std::size_t t = 0; t < b.q.scene.triangles.size() && !matched; ++t) {
          const Triangle& tri = b.q.scene.triangles[t];
          if (tri.material != static_cast<uint32_t>(prim.material)) continue;
          const double pull = b.q.scene.materials[tri.material].two_sided ? apart : 0.0;
          const glm::dvec3 n = glm::normalize(glm::cross(glm::dvec3(tri.p[1] - tri.p[0]), glm::dvec3(tri.p[2] - tri.p[0])));
          matched = true;
          for (std::size_t c = 0; c < 3 && matched; ++c) {
            const uint32_t v = index[k + c];
            const glm::dvec3 want = glm::dvec3(tri.p[c]) + pull * n;
            matched = uv[2 * v] == b.atlas.uv[t][c].x && uv[2 * v + 1] == b.atlas.uv[t][c].y &&
                      std::abs(pos[3 * v] - want.x) < 1e-6 && std::abs(pos[3 * v + 1] - want.y) < 1e-6 &&
                      std::abs(pos[3 * v + 2] - want.z) < 1e-6;
          }
          if (matched) ++found[t];
        }
        EXPECT_TRUE(matched) << mesh.name << " triangle " << k / 3;
      }
    }
  for (std::size_t t = 0; t < found.size(); ++t) EXPECT_EQ(found[t], 1) << t;
}

// A baked glb read back as a scene (a rebake after an edit in Blender): its materials are the
// extras' (no warning about the lightmap texture as a base colour), its faces one-sided (the
// sides were pulled apart), and its atlas is its TEXCOORD_1 at the size it names: every face at
// the UV it was baked at, the same texels, no faces below.
TEST_F(LightmapFiles, ABakedGlbRebakesInItsOwnLayout) {
  Baked b;
  const std::string name = (dir_ / "scene").string();
  const auto files = write_lightmap(name, b.q.scene, b.atlas, b.map, 0.0f, nullptr, 1.5, {});
  const Scene again = import_gltf(files.glb, {});
  for (const std::string& w : again.warnings) EXPECT_EQ(w.find("texture"), std::string::npos) << w;
  ASSERT_EQ(again.triangles.size(), b.q.scene.triangles.size());
  EXPECT_EQ(again.materials.at(again.triangles[0].material).reflectance, glm::vec3(0.5f));
  ASSERT_TRUE(again.lightmap_size.has_value());
  EXPECT_EQ(*again.lightmap_size, (std::array<int, 2>{b.atlas.width, b.atlas.height}));
  ASSERT_NE(b.atlas.width, b.atlas.height);  // a rectangle: its proportions must come back
  const Atlas a = make_atlas(again, {.gutter = 1});
  EXPECT_EQ(a.file_width, b.atlas.width);
  EXPECT_EQ(a.file_height, b.atlas.height);
  EXPECT_EQ(a.width, b.atlas.width);
  EXPECT_EQ(a.height, b.atlas.height);
  std::set<std::array<long, 6>> baked;
  const auto key = [](const std::array<glm::vec2, 3>& uv) {
    std::array<long, 6> k;
    std::array<glm::vec2, 3> sorted = uv;
    std::sort(sorted.begin(), sorted.end(), [](const glm::vec2& p, const glm::vec2& q) { return p.x < q.x || (p.x == q.x && p.y < q.y); });
    for (std::size_t c = 0; c < 3; ++c) k[2 * c] = std::lround(sorted[c].x * 1e5), k[2 * c + 1] = std::lround(sorted[c].y * 1e5);
    return k;
  };
  for (const auto& uv : b.atlas.uv) baked.insert(key(uv));
  for (const auto& uv : a.uv) EXPECT_EQ(baked.count(key(uv)), 1u);
  // A texel size asked for: the file's proportions at that size (to whole blocks of 4).
  const Atlas finer = make_atlas(again, {.texel_size = b.atlas.texel_size / 2, .gutter = 1});
  EXPECT_NEAR(double(finer.file_width) / finer.file_height, double(b.atlas.width) / b.atlas.height, 8.0 / finer.file_height);
  EXPECT_GT(finer.file_height, b.atlas.height);
}

TEST_F(LightmapFiles, WhatHalfFloatsCannotHoldOrAnotherAtlasIsRefused) {
  Baked b;
  const std::string name = (dir_ / "scene").string();
  b.map.combined.at(1, 1) = glm::vec3(1e5f);
  try {
    write_lightmap(name, b.q.scene, b.atlas, b.map, 0.0f, nullptr, 1.0, {});
    FAIL() << "a value above half float's largest was written";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("half float"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(name + "-lightmap.exr"));
  Baked c;
  c.map.error.width -= 1;
  EXPECT_THROW(write_lightmap(name, c.q.scene, c.atlas, c.map, 0.0f, nullptr, 1.0, {}), Error);
  Baked d;
  d.q.scene.triangles.pop_back();
  EXPECT_THROW(write_lightmap(name, d.q.scene, d.atlas, d.map, 0.0f, nullptr, 1.0, {}), Error);
}

}  // namespace
}  // namespace sirad
