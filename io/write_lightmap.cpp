// sirad: a baked lightmap's files (see write_lightmap.h).
#include "io/write_lightmap.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <unordered_map>

#include <fmt/format.h>
#include <glm/geometric.hpp>

#include "io/gltf_build.h"
#include "io/write_gltf.h"
#include "util/error.h"

namespace sirad {

namespace {

// A vertex of the baked glb: where, which way its face looks, its UV; faces share a vertex only
// where all three are the same bits.
struct Vertex {
  glm::vec3 p, n;
  glm::vec2 uv;
  bool operator==(const Vertex& o) const { return std::memcmp(this, &o, sizeof *this) == 0; }
};
struct VertexHash {
  std::size_t operator()(const Vertex& v) const {
    uint32_t bits[8];
    std::memcpy(bits, &v, sizeof bits);
    std::size_t h = 0;
    for (uint32_t b : bits) h = h * 0x9e3779b97f4a7c15ULL + b;
    return h;
  }
};
static_assert(sizeof(Vertex) == 8 * sizeof(float));

void write_glb(const std::string& path, const std::string& exr_name, const Scene& scene, const Atlas& atlas,
               const Lightmap& lightmap, float exposure, const Camera* camera, double aspect) {
  tinygltf::Model m;
  m.asset.version = "2.0";
  m.asset.generator = "sirad";
  m.asset.extras = tinygltf::Value(tinygltf::Value::Object{
      {"sirad_background", gltf::triple(scene.background)},
      {"sirad_lightmap", tinygltf::Value(tinygltf::Value::Object{{"exr", tinygltf::Value(exr_name)},
                                                                  {"texcoord", tinygltf::Value(1)},
                                                                  {"width", tinygltf::Value(atlas.width)},
                                                                  {"height", tinygltf::Value(atlas.height)},
                                                                  {"units", tinygltf::Value(std::string("radiance"))},
                                                                  {"exposure", tinygltf::Value(static_cast<double>(exposure))}})}});
  m.extensionsUsed.push_back("KHR_materials_unlit");
  m.buffers.resize(1);
  // The lightmap's PNG, embedded, and its one texture: linear filtering, clamped at the edges.
  const std::vector<unsigned char> png = png_bytes(path, lightmap.combined, exposure);
  tinygltf::Image image;
  image.name = "lightmap";
  image.mimeType = "image/png";
  image.bufferView = gltf::add_view(m, png.data(), png.size(), 0);
  m.images.push_back(image);
  tinygltf::Sampler sampler;
  sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
  sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
  sampler.wrapS = sampler.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
  m.samplers.push_back(sampler);
  tinygltf::Texture texture;
  texture.source = 0;
  texture.sampler = 0;
  m.textures.push_back(texture);
  for (const Material& mat : scene.materials) {
    tinygltf::Material g;
    g.name = mat.name;
    g.pbrMetallicRoughness.baseColorFactor = {1.0, 1.0, 1.0, 1.0};
    g.pbrMetallicRoughness.baseColorTexture.index = 0;
    g.pbrMetallicRoughness.baseColorTexture.texCoord = 0;
    g.pbrMetallicRoughness.metallicFactor = 0.0;
    g.pbrMetallicRoughness.roughnessFactor = 1.0;
    g.extensions["KHR_materials_unlit"] = tinygltf::Value(tinygltf::Value::Object());
    g.extras = tinygltf::Value(tinygltf::Value::Object{{"sirad_reflectance", gltf::triple(mat.reflectance)},
                                                       {"sirad_emission", gltf::triple(mat.emission)}});
    m.materials.push_back(g);
  }
  // The scene's bounds: how far apart a two-sided face's sides are pulled.
  glm::dvec3 lo(1e300), hi(-1e300);
  for (const Triangle& t : scene.triangles)
    for (const glm::vec3& p : t.p) lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
  const double radius = 0.5 * glm::length(hi - lo);
  const double apart = kSidesApart * radius;
  std::map<uint32_t, std::map<uint32_t, std::vector<uint32_t>>> parts;  // object, material: triangles
  for (std::size_t t = 0; t < scene.triangles.size(); ++t)
    parts[scene.triangles[t].object][scene.triangles[t].material].push_back(static_cast<uint32_t>(t));
  tinygltf::Scene gscene;
  for (const auto& [object, by_material] : parts) {
    tinygltf::Mesh gm;
    gm.name = object < scene.objects.size() ? scene.objects[object] : fmt::format("object {}", object);
    for (const auto& [material, triangles] : by_material) {
      std::unordered_map<Vertex, uint32_t, VertexHash> index_of;
      std::vector<Vertex> vertices;
      std::vector<uint32_t> indices;
      const bool pull = scene.materials[material].two_sided;
      for (uint32_t t : triangles) {
        const Triangle& tri = scene.triangles[t];
        const glm::dvec3 cross = glm::cross(glm::dvec3(tri.p[1] - tri.p[0]), glm::dvec3(tri.p[2] - tri.p[0]));
        const glm::dvec3 n = glm::length(cross) > 0.0 ? glm::normalize(cross) : glm::dvec3(0.0);
        for (std::size_t k = 0; k < 3; ++k) {
          const Vertex v{glm::vec3(glm::dvec3(tri.p[k]) + (pull ? apart : 0.0) * n), glm::vec3(n), atlas.uv[t][k]};
          auto [it, added] = index_of.try_emplace(v, static_cast<uint32_t>(vertices.size()));
          if (added) vertices.push_back(v);
          indices.push_back(it->second);
        }
      }
      std::vector<float> position, normal, uv;
      for (const Vertex& v : vertices) {
        for (int a = 0; a < 3; ++a) position.push_back(v.p[a]), normal.push_back(v.n[a]);
        uv.push_back(v.uv.x), uv.push_back(v.uv.y);
      }
      tinygltf::Primitive prim;
      prim.mode = TINYGLTF_MODE_TRIANGLES;
      prim.material = static_cast<int>(material);
      prim.attributes["POSITION"] = gltf::add_positions(m, position);
      prim.attributes["NORMAL"] = gltf::add_vec3(m, normal);
      prim.attributes["TEXCOORD_0"] = gltf::add_vec2(m, uv);
      prim.attributes["TEXCOORD_1"] = prim.attributes["TEXCOORD_0"];
      prim.indices = gltf::add_indices(m, indices);
      gm.primitives.push_back(prim);
    }
    gltf::add_mesh(m, gscene, std::move(gm));
  }
  if (camera) gltf::add_camera(m, gscene, *camera, glm::vec3(0.5 * (lo + hi)), static_cast<float>(radius), aspect);
  gltf::save_glb(m, std::move(gscene), path);
}

}  // namespace

LightmapFiles write_lightmap(const std::string& name, const Scene& scene, const Atlas& atlas, const Lightmap& lightmap,
                             float exposure, const Camera* camera, double aspect, const Attributes& attributes) {
  const int w = atlas.width, h = atlas.height;
  for (const Image* image : {&lightmap.combined, &lightmap.direct, &lightmap.indirect, &lightmap.error})
    if (image->width != w || image->height != h)
      fail("cannot write {}-lightmap.exr: a lightmap of {}x{} texels for an atlas of {}x{}", name, image->width, image->height, w, h);
  if (atlas.uv.size() != scene.triangles.size())
    fail("cannot write {}-baked.glb: an atlas of {} triangles for a scene of {}", name, atlas.uv.size(), scene.triangles.size());
  LightmapFiles files{name + "-lightmap.exr", name + "-lightmap.png", name + "-baked.glb"};
  Attributes attrs = attributes;
  attrs.emplace_back("sirad.lightmap", std::string("radiance"));
  attrs.emplace_back("sirad.texel_size", atlas.texel_size);
  if (lightmap.coverage.size() != lightmap.combined.pixels.size())
    fail("cannot write {}-lightmap.exr: coverage of {} texels for {}", name, lightmap.coverage.size(), lightmap.combined.pixels.size());
  Image coverage;
  coverage.width = w, coverage.height = h;
  coverage.pixels.reserve(lightmap.coverage.size());
  for (float c : lightmap.coverage) coverage.pixels.emplace_back(c);
  write_exr_layers(files.exr,
                   {{"", &lightmap.combined},
                    {"direct", &lightmap.direct},
                    {"indirect", &lightmap.indirect},
                    {"error", &lightmap.error},
                    {"coverage", &coverage}},
                   attrs, ExrPixel::half);
  write_png(files.png, lightmap.combined, exposure);
  write_glb(files.glb, std::filesystem::path(files.exr).filename().string(), scene, atlas, lightmap, exposure, camera, aspect);
  return files;
}

}  // namespace sirad
