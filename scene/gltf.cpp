// sirad: glTF 2.0 scenes (.gltf and .glb) through tinygltf (Debian's libtinygltf-dev: a small,
// maintained reader of the whole format, .glb and embedded or external buffers and images
// included; assimp would bring a hundred formats and their attack surface for one).
//
// What is read: the default scene's node tree with its transforms (matrix or TRS), every
// triangle primitive (modes TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN) of its meshes, in metres
// and Y-up as glTF defines; per material pbrMetallicRoughness.baseColorFactor as the diffuse
// reflectance (times the mean linear colour of a baseColorTexture, said in a warning),
// emissiveFactor times KHR_materials_emissive_strength as emitted radiance, doubleSided as
// Material::two_sided (Blender exports doubleSided unless backface culling is on: as Cycles
// renders it); TEXCOORD_1, the lightmap UV set, as each triangle's UvMap (the bake's layout);
// the first perspective camera in the tree as the scene's camera. Punctual lights
// (KHR_lights_punctual) are refused: sirad's light comes from emitting surfaces. Everything is
// validated as the OBJ reader validates: one line naming the file and the element.
//
// Bounded whatever the file says: its JSON's nesting is checked before tinygltf parses it
// (tinygltf converts `extras` recursively); external buffers and images are regular files in
// the scene's folder (relative URIs that stay there after symlinks are resolved; no absolute
// paths, no schemes but data:), checked before anything opens them; the node tree's triangles
// are counted before any is made (a mesh instanced by many nodes); an image's size is read from
// its header before it is decoded.
#include <sys/stat.h>

#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <numbers>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include "scene/gltf.h"
#include "scene/import.h"
#include "scene/scene.h"
#include "util/error.h"
#include "util/json_bounded.h"

namespace sirad {

namespace {

using import::kDefaultReflectance;
using import::kMaxTriangles;
using import::srgb_to_linear;
constexpr std::size_t kMaxNodes = std::size_t{1} << 20;
// The most pixels of an image decoded (8192 x 8192: 512 MiB at 16 bits RGBA). A texture is
// reduced to its mean colour, which a smaller copy of it gives as well.
constexpr std::size_t kMaxTexturePixels = std::size_t{1} << 26;

// A name from the file as it may appear in messages and outputs.
std::string clean(const std::string& name) { return import::without_controls(name, 200); }

class GltfReader {
 public:
  // `radiance`: read the solution sirad wrote as well (import_gltf).
  GltfReader(std::string path, const tinygltf::Model& model, std::vector<std::array<glm::vec3, 3>>* radiance)
      : path_(std::move(path)), m_(model), radiance_(radiance) {}

  Scene read(const ImportOptions& options) {
    scene_.name = path_;
    scene_.objects.clear();
    for (const auto& ext : m_.extensionsRequired)
      if (ext != "KHR_materials_emissive_strength" && ext != "KHR_materials_unlit" && ext != "KHR_texture_transform")
        fail("{}: requires the glTF extension {}, which sirad does not read", path_, clean(ext));
    if (!m_.lights.empty())
      fail("{}: has {} punctual light{} (KHR_lights_punctual), which sirad cannot use: its light comes from emitting "
           "surfaces (give a mesh an emissive material, e.g. Blender's Emission strength)",
           path_, m_.lights.size(), m_.lights.size() == 1 ? "" : "s");
    if (m_.scenes.empty()) fail("{}: no scene", path_);
    if (m_.asset.extras.Has("sirad_lightmap")) {  // a glb sirad baked: its lightmap's size
      const tinygltf::Value& l = m_.asset.extras.Get("sirad_lightmap");
      if (l.IsObject() && l.Has("width") && l.Has("height")) {
        const tinygltf::Value &w = l.Get("width"), &h = l.Get("height");
        if (!w.IsInt() || !h.IsInt() || w.Get<int>() < 1 || w.Get<int>() > 16384 || h.Get<int>() < 1 || h.Get<int>() > 16384)
          fail("{}: the asset's sirad_lightmap width and height are not whole numbers in 1..16384", path_);
        scene_.lightmap_size = std::array<int, 2>{w.Get<int>(), h.Get<int>()};
      }
    }
    if (m_.asset.extras.Has("sirad_background"))
      scene_.background = glm::vec3(sirad_triple(m_.asset.extras.Get("sirad_background"), "the asset's sirad_background", 0.0, 3.0e38));
    const int which = m_.defaultScene >= 0 ? m_.defaultScene : 0;
    if (which >= static_cast<int>(m_.scenes.size())) fail("{}: default scene {} does not exist", path_, which);
    // The node tree, depth first, each node once (a file whose children form a cycle is refused).
    std::vector<char> seen(m_.nodes.size(), 0);
    struct Item {
      int node;
      glm::dmat4 parent;
    };
    std::vector<Item> stack;
    const auto& roots = m_.scenes[static_cast<std::size_t>(which)].nodes;
    count_triangles(roots);
    for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.push_back({*it, glm::dmat4(1.0)});
    std::size_t visited = 0;
    while (!stack.empty()) {
      Item item = stack.back();
      stack.pop_back();
      if (item.node < 0 || item.node >= static_cast<int>(m_.nodes.size())) fail("{}: node {} does not exist", path_, item.node);
      if (seen[static_cast<std::size_t>(item.node)]) fail("{}: node {} is reached twice (a cycle or a shared child)", path_, item.node);
      seen[static_cast<std::size_t>(item.node)] = 1;
      if (++visited > kMaxNodes) fail("{}: more than {} nodes", path_, kMaxNodes);
      const tinygltf::Node& n = m_.nodes[static_cast<std::size_t>(item.node)];
      const glm::dmat4 world = item.parent * local(n, item.node);
      if (n.mesh >= 0) mesh(n, item.node, world, options);
      if (n.camera >= 0 && !scene_.camera) camera(n, item.node, world);
      for (auto it = n.children.rbegin(); it != n.children.rend(); ++it) stack.push_back({*it, world});
    }
    if (scene_.objects.empty()) scene_.objects.push_back("(unnamed)");
    if (scene_.triangles.empty()) {
      if (skipped_ > 0) fail("{}: scene has no triangles ({} skipped as degenerate)", path_, skipped_);
      fail("{}: scene has no triangles", path_);
    }
    bool emits = false;
    for (const Material& mat : scene_.materials) emits = emits || mat.emits();
    if (!emits) fail("{}: scene has no emitter (no material with an emissiveFactor above 0)", path_);
    if (flat_uv_ > 0)
      scene_.warnings.push_back(fmt::format("{}: {} triangles have no area in TEXCOORD_1: they get texels of their own in the lightmap",
                                            path_, flat_uv_));
    return scene_;
  }

 private:
  // The triangles the node tree under `roots` makes, each mesh once per node that uses it, counted
  // from the accessors' counts before any is made: refused past kMaxTriangles. The walk refuses
  // what the tree's expansion refuses (a missing node, a node reached twice, too many nodes).
  void count_triangles(const std::vector<int>& roots) const {
    constexpr uint64_t kMeshCap = uint64_t{1} << 40;  // times kMaxNodes, still far from overflowing
    std::vector<uint64_t> of_mesh(m_.meshes.size(), 0);
    for (std::size_t k = 0; k < m_.meshes.size(); ++k)
      for (const tinygltf::Primitive& prim : m_.meshes[k].primitives) {
        auto pos = prim.attributes.find("POSITION");
        const int accessor = prim.indices >= 0 ? prim.indices : pos != prim.attributes.end() ? pos->second : -1;
        if (accessor < 0 || accessor >= static_cast<int>(m_.accessors.size())) continue;  // refused when it is read
        const uint64_t n = std::min<uint64_t>(m_.accessors[static_cast<std::size_t>(accessor)].count, kMeshCap);
        const bool strip_or_fan = prim.mode == TINYGLTF_MODE_TRIANGLE_STRIP || prim.mode == TINYGLTF_MODE_TRIANGLE_FAN;
        const uint64_t made = prim.mode == TINYGLTF_MODE_TRIANGLES ? n / 3 : strip_or_fan && n >= 3 ? n - 2 : 0;
        of_mesh[k] = std::min(of_mesh[k] + made, kMeshCap);
      }
    std::vector<char> seen(m_.nodes.size(), 0);
    std::vector<int> stack(roots.rbegin(), roots.rend());
    std::size_t visited = 0;
    uint64_t total = 0;
    while (!stack.empty()) {
      const int node = stack.back();
      stack.pop_back();
      if (node < 0 || node >= static_cast<int>(m_.nodes.size())) fail("{}: node {} does not exist", path_, node);
      if (seen[static_cast<std::size_t>(node)]) fail("{}: node {} is reached twice (a cycle or a shared child)", path_, node);
      seen[static_cast<std::size_t>(node)] = 1;
      if (++visited > kMaxNodes) fail("{}: more than {} nodes", path_, kMaxNodes);
      const tinygltf::Node& n = m_.nodes[static_cast<std::size_t>(node)];
      if (n.mesh >= 0 && n.mesh < static_cast<int>(of_mesh.size())) total += of_mesh[static_cast<std::size_t>(n.mesh)];
      stack.insert(stack.end(), n.children.rbegin(), n.children.rend());
    }
    if (total > kMaxTriangles)
      fail("{}: its node tree makes {} triangles (each mesh once per node that uses it), more than {}", path_, total, kMaxTriangles);
  }

  std::string where(int node) const {
    const auto& n = m_.nodes[static_cast<std::size_t>(node)];
    return n.name.empty() ? fmt::format("node {}", node) : fmt::format("node {} '{}'", node, clean(n.name));
  }

  glm::dmat4 local(const tinygltf::Node& n, int node) const {
    if (!n.matrix.empty()) {
      if (n.matrix.size() != 16) fail("{}: {}: matrix has {} numbers, not 16", path_, where(node), n.matrix.size());
      glm::dmat4 m;
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) m[c][r] = n.matrix[static_cast<std::size_t>(4 * c + r)];  // column-major
      for (double v : n.matrix)
        if (!std::isfinite(v)) fail("{}: {}: matrix is not finite", path_, where(node));
      return m;
    }
    glm::dmat4 t(1.0), r(1.0), s(1.0);
    if (!n.translation.empty()) {
      if (n.translation.size() != 3) fail("{}: {}: translation is not 3 numbers", path_, where(node));
      t = glm::translate(glm::dmat4(1.0), glm::dvec3(n.translation[0], n.translation[1], n.translation[2]));
    }
    if (!n.rotation.empty()) {
      if (n.rotation.size() != 4) fail("{}: {}: rotation is not 4 numbers", path_, where(node));
      glm::dquat q(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);  // glTF: x, y, z, w
      if (!(glm::length(q) > 0.0)) fail("{}: {}: rotation is not a unit quaternion", path_, where(node));
      r = glm::mat4_cast(glm::normalize(q));
    }
    if (!n.scale.empty()) {
      if (n.scale.size() != 3) fail("{}: {}: scale is not 3 numbers", path_, where(node));
      s = glm::scale(glm::dmat4(1.0), glm::dvec3(n.scale[0], n.scale[1], n.scale[2]));
    }
    glm::dmat4 m = t * r * s;
    for (int c = 0; c < 4; ++c)
      for (int k = 0; k < 4; ++k)
        if (!std::isfinite(m[c][k])) fail("{}: {}: transform is not finite", path_, where(node));
    return m;
  }

  // The bytes of accessor `index` checked against its buffer: element e's component k is at
  // data + e * stride + k * component size.
  struct View {
    const unsigned char* data = nullptr;
    std::size_t count = 0, stride = 0;
    int component = 0, components = 0;
  };
  View view(int index, const std::string& what) const {
    if (index < 0 || index >= static_cast<int>(m_.accessors.size())) fail("{}: {}: accessor {} does not exist", path_, what, index);
    const tinygltf::Accessor& a = m_.accessors[static_cast<std::size_t>(index)];
    if (a.sparse.isSparse) fail("{}: {}: sparse accessors are not supported", path_, what);
    if (a.bufferView < 0 || a.bufferView >= static_cast<int>(m_.bufferViews.size()))
      fail("{}: {}: accessor {} has no buffer view", path_, what, index);
    const tinygltf::BufferView& bv = m_.bufferViews[static_cast<std::size_t>(a.bufferView)];
    if (bv.buffer < 0 || bv.buffer >= static_cast<int>(m_.buffers.size())) fail("{}: {}: buffer {} does not exist", path_, what, bv.buffer);
    const auto& buffer = m_.buffers[static_cast<std::size_t>(bv.buffer)].data;
    View v;
    v.component = tinygltf::GetComponentSizeInBytes(static_cast<uint32_t>(a.componentType));
    v.components = tinygltf::GetNumComponentsInType(static_cast<uint32_t>(a.type));
    if (v.component <= 0 || v.components <= 0) fail("{}: {}: accessor {} has a bad type", path_, what, index);
    const int stride = a.ByteStride(bv);
    if (stride <= 0) fail("{}: {}: accessor {} has a bad byte stride", path_, what, index);
    v.stride = static_cast<std::size_t>(stride);
    v.count = a.count;
    const std::size_t element = static_cast<std::size_t>(v.component) * static_cast<std::size_t>(v.components);
    if (bv.byteOffset > buffer.size() || bv.byteLength > buffer.size() - bv.byteOffset)
      fail("{}: {}: buffer view {} runs past its buffer", path_, what, a.bufferView);
    if (v.count > 0) {
      if (a.byteOffset > bv.byteLength || (v.count - 1) > (bv.byteLength - a.byteOffset) / v.stride ||
          a.byteOffset + (v.count - 1) * v.stride + element > bv.byteLength)
        fail("{}: {}: accessor {} runs past its buffer view", path_, what, index);
    }
    v.data = buffer.data() + bv.byteOffset + a.byteOffset;
    return v;
  }

  uint32_t material(int index) {
    auto it = material_of_.find(index);
    if (it != material_of_.end()) return it->second;
    Material mat;
    if (index < 0) {
      mat = {"default", glm::vec3(kDefaultReflectance), glm::vec3(0.0f)};
      scene_.warnings.push_back(fmt::format("{}: a mesh has no material: it takes the default, reflectance {} and one-sided",
                                            path_, kDefaultReflectance));
    } else {
      if (index >= static_cast<int>(m_.materials.size())) fail("{}: material {} does not exist", path_, index);
      const tinygltf::Material& g = m_.materials[static_cast<std::size_t>(index)];
      mat.name = g.name.empty() ? fmt::format("material {}", index) : clean(g.name);
      const std::string what = fmt::format("material '{}'", mat.name);
      const auto& base = g.pbrMetallicRoughness.baseColorFactor;
      if (base.size() != 4) fail("{}: {}: baseColorFactor is not 4 numbers", path_, what);
      glm::dvec3 rho(base[0], base[1], base[2]);
      // (A file sirad wrote says its reflectance in the extras, below: its texture is the bake.)
      if (int t = g.pbrMetallicRoughness.baseColorTexture.index; t >= 0 && !g.extras.Has("sirad_reflectance"))
        rho *= texture_mean(t, what);
      const auto& e = g.emissiveFactor;
      if (e.size() != 3) fail("{}: {}: emissiveFactor is not 3 numbers", path_, what);
      double strength = 1.0;
      if (auto ext = g.extensions.find("KHR_materials_emissive_strength"); ext != g.extensions.end()) {
        const tinygltf::Value& v = ext->second.Get("emissiveStrength");
        if (!v.IsNumber()) fail("{}: {}: KHR_materials_emissive_strength without a number", path_, what);
        strength = v.GetNumberAsDouble();
      }
      glm::dvec3 emission = glm::dvec3(e[0], e[1], e[2]) * strength;
      for (int k = 0; k < 3; ++k) {
        if (!(rho[k] >= 0.0 && rho[k] <= 1.0)) fail("{}: {}: base colour {} outside [0, 1]", path_, what, rho[k]);
        if (!std::isfinite(emission[k]) || emission[k] > 3.0e38) fail("{}: {}: emission {} is not finite", path_, what, emission[k]);
        if (emission[k] < 0.0) fail("{}: {}: emission {} is negative", path_, what, emission[k]);
      }
      if (g.emissiveTexture.index >= 0)
        scene_.warnings.push_back(fmt::format("{}: {}: its emissive texture is not read; emissiveFactor is used", path_, what));
      // A file sirad wrote: its viewers' colours are the solution (an unlit white base), the
      // scene's reflectance and emission are in the extras.
      if (g.extras.Has("sirad_reflectance")) rho = sirad_triple(g.extras.Get("sirad_reflectance"), what + " sirad_reflectance", 0.0, 1.0);
      if (g.extras.Has("sirad_emission")) emission = sirad_triple(g.extras.Get("sirad_emission"), what + " sirad_emission", 0.0, 3.0e38);
      mat.reflectance = glm::vec3(rho);
      mat.emission = glm::vec3(emission);
      mat.two_sided = g.doubleSided;
    }
    const auto slot = static_cast<uint32_t>(scene_.materials.size());
    scene_.materials.push_back(mat);
    material_of_[index] = slot;
    return slot;
  }

  // The mean linear colour of texture `t`'s image (sRGB-encoded, as glTF's base colour is), with
  // a warning that the texture is reduced to it; 1 (and a warning) when its image is not there.
  glm::dvec3 texture_mean(int t, const std::string& what) {
    const auto source = t < static_cast<int>(m_.textures.size()) ? m_.textures[static_cast<std::size_t>(t)].source : -1;
    if (source < 0 || source >= static_cast<int>(m_.images.size())) {
      scene_.warnings.push_back(fmt::format("{}: {}: its base colour texture has no image; baseColorFactor is used", path_, what));
      return glm::dvec3(1.0);
    }
    const tinygltf::Image& im = m_.images[static_cast<std::size_t>(source)];
    const std::size_t pixels = static_cast<std::size_t>(std::max(im.width, 0)) * static_cast<std::size_t>(std::max(im.height, 0));
    if (pixels == 0 || im.component < 3 || (im.bits != 8 && im.bits != 16) ||
        im.image.size() < pixels * static_cast<std::size_t>(im.component) * static_cast<std::size_t>(im.bits / 8)) {
      scene_.warnings.push_back(fmt::format("{}: {}: its base colour texture '{}' could not be read; baseColorFactor is used",
                                            path_, what, clean(im.uri.empty() ? im.name : im.uri)));
      return glm::dvec3(1.0);
    }
    glm::dvec3 sum(0.0);
    const double max = im.bits == 8 ? 255.0 : 65535.0;
    for (std::size_t p = 0; p < pixels; ++p)
      for (int c = 0; c < 3; ++c) {
        std::size_t at = (p * static_cast<std::size_t>(im.component) + static_cast<std::size_t>(c)) * static_cast<std::size_t>(im.bits / 8);
        double v = im.bits == 8 ? im.image[at] : (im.image[at] | (im.image[at + 1] << 8));
        sum[c] += srgb_to_linear(v / max);
      }
    glm::dvec3 mean = sum / static_cast<double>(pixels);
    scene_.warnings.push_back(fmt::format("{}: {}: its base colour texture is reduced to its mean colour ({:.3f} {:.3f} {:.3f}): "
                                          "radiosity is per patch", path_, what, mean.x, mean.y, mean.z));
    return mean;
  }

  // The primitive's TEXCOORD_1 (its lightmap UV set), one per vertex; empty where it has none.
  // Float, or normalized unsigned byte or short, VEC2, as glTF allows for texture coordinates.
  std::vector<glm::dvec2> lightmap_uv(const tinygltf::Primitive& prim, std::size_t vertices, const std::string& what) const {
    auto it = prim.attributes.find("TEXCOORD_1");
    if (it == prim.attributes.end()) return {};
    View v = view(it->second, what + " TEXCOORD_1");
    const auto& acc = m_.accessors[static_cast<std::size_t>(it->second)];
    const int type = acc.componentType;
    const bool is_float = type == TINYGLTF_COMPONENT_TYPE_FLOAT;
    if (v.components != 2 || v.count != vertices ||
        !(is_float || (acc.normalized && (type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE || type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT))))
      fail("{}: {}: TEXCOORD_1 is not VEC2 (float, or normalized unsigned byte or short) with one value per vertex", path_, what);
    std::vector<glm::dvec2> uv(v.count);
    for (std::size_t i = 0; i < v.count; ++i)
      for (int k = 0; k < 2; ++k) {
        const unsigned char* at = v.data + i * v.stride + static_cast<std::size_t>(k * v.component);
        double x = 0;
        if (is_float) {
          float f;
          std::memcpy(&f, at, sizeof f);
          x = f;
        } else if (v.component == 1) {
          x = at[0] / 255.0;
        } else {
          x = (at[0] | (at[1] << 8)) / 65535.0;
        }
        if (!std::isfinite(x) || std::abs(x) > 1e6) fail("{}: {}: TEXCOORD_1 of vertex {} is not finite or beyond 1e6", path_, what, i);
        uv[i][k] = x;
      }
    return uv;
  }

  void mesh(const tinygltf::Node& n, int node, const glm::dmat4& world, const ImportOptions& options) {
    if (n.mesh >= static_cast<int>(m_.meshes.size())) fail("{}: {}: mesh {} does not exist", path_, where(node), n.mesh);
    const tinygltf::Mesh& mesh = m_.meshes[static_cast<std::size_t>(n.mesh)];
    const uint32_t object = static_cast<uint32_t>(scene_.objects.size());
    scene_.objects.push_back(clean(!n.name.empty() ? n.name : !mesh.name.empty() ? mesh.name : fmt::format("node {}", node)));
    // A transform that mirrors (negative determinant) turns counter-clockwise into clockwise.
    const bool mirrored = glm::determinant(glm::dmat3(world)) < 0.0;
    for (std::size_t p = 0; p < mesh.primitives.size(); ++p) {
      const tinygltf::Primitive& prim = mesh.primitives[p];
      const std::string what = fmt::format("{} primitive {}", where(node), p);
      if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != TINYGLTF_MODE_TRIANGLE_STRIP && prim.mode != TINYGLTF_MODE_TRIANGLE_FAN)
        fail("{}: {}: mode {} is points or lines, not a surface", path_, what, prim.mode);
      auto pos = prim.attributes.find("POSITION");
      if (pos == prim.attributes.end()) fail("{}: {}: no POSITION", path_, what);
      View v = view(pos->second, what + " POSITION");
      const auto& acc = m_.accessors[static_cast<std::size_t>(pos->second)];
      if (acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT || v.components != 3)
        fail("{}: {}: POSITION is not float VEC3", path_, what);
      std::vector<glm::vec3> points(v.count);
      for (std::size_t i = 0; i < v.count; ++i) {
        float xyz[3];
        std::memcpy(xyz, v.data + i * v.stride, sizeof xyz);
        glm::dvec4 q = world * glm::dvec4(xyz[0], xyz[1], xyz[2], 1.0);
        for (int k = 0; k < 3; ++k)
          if (!std::isfinite(q[k]) || std::abs(q[k]) > 1e30) fail("{}: {}: vertex {} is not finite", path_, what, i);
        points[i] = glm::vec3(q);
      }
      std::vector<uint32_t> index;
      if (prim.indices >= 0) {
        View iv = view(prim.indices, what + " indices");
        if (iv.components != 1) fail("{}: {}: indices are not scalars", path_, what);
        index.resize(iv.count);
        for (std::size_t i = 0; i < iv.count; ++i) {
          const unsigned char* at = iv.data + i * iv.stride;
          uint32_t k = 0;
          if (iv.component == 1) k = at[0];
          else if (iv.component == 2) k = static_cast<uint32_t>(at[0] | (at[1] << 8));
          else std::memcpy(&k, at, 4);
          if (k >= points.size()) fail("{}: {}: index {} out of range ({} vertices)", path_, what, k, points.size());
          index[i] = k;
        }
      } else {
        index.resize(points.size());
        for (std::size_t i = 0; i < index.size(); ++i) index[i] = static_cast<uint32_t>(i);
      }
      const uint32_t mat = material(prim.material);
      std::vector<glm::vec3> radiance;  // per vertex, when the solution is read
      if (radiance_) {
        auto r = prim.attributes.find("_RADIANCE");
        if (r == prim.attributes.end()) fail("{}: {}: no _RADIANCE: not a solution sirad wrote", path_, what);
        View rv = view(r->second, what + " _RADIANCE");
        if (m_.accessors[static_cast<std::size_t>(r->second)].componentType != TINYGLTF_COMPONENT_TYPE_FLOAT || rv.components != 3 ||
            rv.count != points.size())
          fail("{}: {}: _RADIANCE is not float VEC3 with one value per vertex", path_, what);
        radiance.resize(rv.count);
        for (std::size_t i = 0; i < rv.count; ++i) {
          std::memcpy(&radiance[i], rv.data + i * rv.stride, sizeof(float) * 3);
          for (int k = 0; k < 3; ++k)
            if (!std::isfinite(radiance[i][k])) fail("{}: {}: _RADIANCE of vertex {} is not finite", path_, what, i);
        }
      }
      const std::vector<glm::dvec2> uv1 = lightmap_uv(prim, points.size(), what);
      auto add = [&](uint32_t a, uint32_t b, uint32_t c) {
        if (mirrored) std::swap(b, c);
        Triangle t;
        t.p = {points[a], points[b], points[c]};
        t.material = mat;
        t.object = object;
        glm::dvec3 e = glm::cross(glm::dvec3(t.p[1] - t.p[0]), glm::dvec3(t.p[2] - t.p[0]));
        if (!(glm::length(e) > 0.0)) {
          if (!options.skip_degenerate)
            fail("{}: {}: degenerate triangle (zero area) with vertices {}, {}, {} (skipping degenerate triangles drops them)", path_,
                 what, a, b, c);
          ++skipped_;
          return;
        }
        if (scene_.triangles.size() >= kMaxTriangles) fail("{}: more than {} triangles", path_, kMaxTriangles);
        if (!uv1.empty()) {
          UvMap map;
          if (make_uv_map({glm::dvec3(t.p[0]), glm::dvec3(t.p[1]), glm::dvec3(t.p[2])}, {uv1[a], uv1[b], uv1[c]}, map)) {
            t.uv_map = static_cast<uint32_t>(scene_.uv_maps.size());
            scene_.uv_maps.push_back(map);
          } else {
            ++flat_uv_;
          }
        }
        scene_.triangles.push_back(t);
        if (radiance_) radiance_->push_back({radiance[a], radiance[b], radiance[c]});
      };
      if (prim.mode == TINYGLTF_MODE_TRIANGLES) {
        if (index.size() % 3 != 0) fail("{}: {}: {} indices are not whole triangles", path_, what, index.size());
        for (std::size_t i = 0; i + 2 < index.size(); i += 3) add(index[i], index[i + 1], index[i + 2]);
      } else if (prim.mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        for (std::size_t i = 0; i + 2 < index.size(); ++i)
          if (i % 2 == 0) add(index[i], index[i + 1], index[i + 2]);
          else add(index[i + 1], index[i], index[i + 2]);
      } else {
        for (std::size_t i = 1; i + 1 < index.size(); ++i) add(index[0], index[i], index[i + 1]);
      }
    }
  }

  // glTF cameras look along their node's -Z with +Y up; yfov is the vertical field of view.
  void camera(const tinygltf::Node& n, int node, const glm::dmat4& world) {
    if (n.camera >= static_cast<int>(m_.cameras.size())) fail("{}: {}: camera {} does not exist", path_, where(node), n.camera);
    const tinygltf::Camera& c = m_.cameras[static_cast<std::size_t>(n.camera)];
    if (c.type != "perspective") {
      scene_.warnings.push_back(fmt::format("{}: {}: camera '{}' is {}, not perspective: not used", path_, where(node), clean(c.name), clean(c.type)));
      return;
    }
    if (const double a = c.perspective.aspectRatio; a > 0.0) {  // the default image shape
      if (!(a >= 1e-3 && a <= 1e3)) fail("{}: {}: camera aspectRatio {} outside [0.001, 1000]", path_, where(node), a);
      scene_.camera_aspect = a;
    }
    if (n.extras.Has("sirad_camera")) {  // the view sirad's images showed, exactly
      const tinygltf::Value& spec = n.extras.Get("sirad_camera");
      if (!spec.IsString()) fail("{}: {}: sirad_camera is not a string", path_, where(node));
      try {
        scene_.camera = parse_camera(spec.Get<std::string>());
      } catch (const Error& e) {
        fail("{}: {}: sirad_camera: {}", path_, where(node), e.what());
      }
      return;
    }
    const double fov = c.perspective.yfov * 180.0 / std::numbers::pi;
    if (!(fov > 0.0 && fov < 180.0)) fail("{}: {}: camera yfov {} outside (0, pi)", path_, where(node), c.perspective.yfov);
    glm::dvec3 eye(world * glm::dvec4(0, 0, 0, 1)), forward(world * glm::dvec4(0, 0, -1, 0)), up(world * glm::dvec4(0, 1, 0, 0));
    if (!(glm::length(forward) > 0.0) || !(glm::length(glm::cross(forward, up)) > 0.0))
      fail("{}: {}: camera transform has no view direction", path_, where(node));
    Camera cam;
    cam.eye = glm::vec3(eye);
    cam.look_at = glm::vec3(eye + glm::normalize(forward));
    cam.up = glm::vec3(glm::normalize(up));
    cam.vfov_deg = static_cast<float>(fov);
    scene_.camera = cam;
  }

  std::string path_;
  const tinygltf::Model& m_;
  Scene scene_;
  std::map<int, uint32_t> material_of_;
  std::size_t skipped_ = 0;
  std::size_t flat_uv_ = 0;  // triangles whose TEXCOORD_1 has no area
  std::vector<std::array<glm::vec3, 3>>* radiance_ = nullptr;

  // Three numbers in [lo, hi] from an `extras` value sirad wrote, or one error naming `what`.
  glm::dvec3 sirad_triple(const tinygltf::Value& v, const std::string& what, double lo, double hi) const {
    if (!v.IsArray() || v.ArrayLen() != 3) fail("{}: {}: not 3 numbers", path_, what);
    glm::dvec3 out;
    for (int k = 0; k < 3; ++k) {
      const tinygltf::Value& x = v.Get(k);
      if (!x.IsNumber()) fail("{}: {}: not 3 numbers", path_, what);
      out[k] = x.GetNumberAsDouble();
      if (!(out[k] >= lo && out[k] <= hi)) fail("{}: {}: {} outside [{}, {}]", path_, what, out[k], lo, hi);
    }
    return out;
  }
};

// What tinygltf may read beside the scene: regular files under the scene's folder. tinygltf
// looks a relative URI up as FOLDER/URI (then ./URI) with FileExists and reads it with
// ReadWholeFile; both are checked here, before anything is opened (its own FileExists opens the
// file, and a FIFO blocks that open). A refusal is kept to be the load's one error: tinygltf
// turns a missing image into a warning.
struct Confinement {
  std::string folder;        // as tinygltf joins it with a URI
  std::filesystem::path canonical_folder;
  bool outside = false;      // ImportOptions::outside_uris: relative URIs may leave the folder
  std::string refused;       // the first refusal, or ""
};

// `joined` (FOLDER/URI) if it is a regular file under the folder once symlinks are resolved;
// "" (and a refusal kept) if not.
std::filesystem::path confined(Confinement& c, const std::string& joined) {
  namespace fs = std::filesystem;
  auto refuse = [&](const std::string& uri, const char* why) {
    if (c.refused.empty()) c.refused = fmt::format("URI '{}' {}", import::printable(uri), why);
    return fs::path();
  };
  const std::string prefix = c.folder.ends_with('/') ? c.folder : c.folder + '/';
  if (joined.size() <= prefix.size() || !joined.starts_with(prefix))
    return {};  // tinygltf's second try, ./URI: nothing is read from the working folder
  const std::string uri = joined.substr(prefix.size());
  if (uri.front() == '/') return refuse(uri, "is an absolute path: external buffers and images are read from the scene's folder");
  const std::size_t colon = uri.find(':');
  if (colon != std::string::npos && uri.find('/') > colon)
    return refuse(uri, "has a scheme: only data: URIs and paths relative to the scene's folder are read");
  std::error_code ec;
  const fs::path file = fs::canonical(joined, ec);
  if (ec) return {};  // no such file: tinygltf says so
  const fs::path rel = file.lexically_relative(c.canonical_folder);
  if (!c.outside && (rel.empty() || *rel.begin() == ".."))
    return refuse(uri, "names a file outside the scene's folder (--allow-outside-uris reads it)");
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0) return {};
  if (!S_ISREG(st.st_mode)) return refuse(uri, "is not a regular file (a FIFO, a device or a folder)");
  return file;
}

bool exists_confined(const std::string& joined, void* user) {
  return !confined(*static_cast<Confinement*>(user), joined).empty();
}

// Read as the scene is (import::read_file: a regular file of at most 2 GiB, opened without
// blocking), after the same check (the file may have changed since tinygltf found it).
bool read_confined(std::vector<unsigned char>* out, std::string* err, const std::string& joined, void* user) {
  try {
    const std::filesystem::path file = confined(*static_cast<Confinement*>(user), joined);
    if (file.empty()) fail("{}: not readable here", joined);
    const std::string bytes = import::read_file(file, joined);
    out->assign(bytes.begin(), bytes.end());
    return true;
  } catch (const Error& e) {
    if (err) *err += std::string(e.what()) + "\n";
    return false;
  }
}

bool no_write(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "sirad does not write through the glTF reader\n";
  return false;
}

uint32_t big_endian(const unsigned char* p) {
  return static_cast<uint32_t>(p[0]) << 24 | static_cast<uint32_t>(p[1]) << 16 | static_cast<uint32_t>(p[2]) << 8 | p[3];
}

// Width and height from a PNG's IHDR or a JPEG's start-of-frame (glTF's two image formats), or
// {0, 0} when `bytes` is neither.
std::pair<uint64_t, uint64_t> image_size(const unsigned char* bytes, std::size_t size) {
  static constexpr unsigned char kPng[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (size >= 24 && std::memcmp(bytes, kPng, 8) == 0 && std::memcmp(bytes + 12, "IHDR", 4) == 0)
    return {big_endian(bytes + 16), big_endian(bytes + 20)};
  if (size < 4 || bytes[0] != 0xff || bytes[1] != 0xd8) return {0, 0};
  std::size_t at = 2;  // JPEG: markers FF xx, each but the standalone ones followed by a big-endian length
  while (at + 4 <= size) {
    if (bytes[at] != 0xff) return {0, 0};
    const unsigned char marker = bytes[at + 1];
    if (marker == 0xff) {  // fill byte
      ++at;
      continue;
    }
    if (marker == 0x01 || (marker >= 0xd0 && marker <= 0xd7)) {
      at += 2;
      continue;
    }
    const std::size_t length = static_cast<std::size_t>(bytes[at + 2]) << 8 | bytes[at + 3];
    const bool frame = marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc;
    if (frame && at + 9 <= size)
      return {static_cast<uint64_t>(bytes[at + 7]) << 8 | bytes[at + 8], static_cast<uint64_t>(bytes[at + 5]) << 8 | bytes[at + 6]};
    if (marker == 0xda || marker == 0xd9 || length < 2) return {0, 0};  // image data before any frame
    at += 2 + length;
  }
  return {0, 0};
}

// Images are decoded (a base colour texture's mean colour is used) only once their header says
// they are at most kMaxTexturePixels; a PNG or JPEG larger is refused, an image of another format
// is left undecoded (its texture then warns and baseColorFactor is used).
bool load_image_bounded(tinygltf::Image* image, const int index, std::string* err, std::string* warn, int req_width,
                        int req_height, const unsigned char* bytes, int size, void* user) {
  const auto [width, height] = image_size(bytes, static_cast<std::size_t>(std::max(size, 0)));
  if (width == 0 || height == 0) return true;
  if (width * height > kMaxTexturePixels) {
    auto& c = *static_cast<Confinement*>(user);
    if (c.refused.empty())
      c.refused = fmt::format("image {} '{}' is {} x {} pixels, more than {} (a texture counts by its mean colour: a smaller copy "
                              "gives the same)",
                              index, import::printable(image->uri.empty() ? image->name : image->uri), width, height, kMaxTexturePixels);
    if (err) *err += c.refused + "\n";
    return false;
  }
  return tinygltf::LoadImageData(image, index, err, warn, req_width, req_height, bytes, size, nullptr);
}

// The JSON of a .gltf, or of a .glb's first chunk ("" when the .glb is too short to have one:
// tinygltf refuses it).
std::string_view json_of(const std::string& bytes, bool binary) {
  if (!binary) return bytes;
  if (bytes.size() < 20) return {};
  const auto* p = reinterpret_cast<const unsigned char*>(bytes.data());
  const std::size_t length = static_cast<std::size_t>(p[12]) | static_cast<std::size_t>(p[13]) << 8 |
                             static_cast<std::size_t>(p[14]) << 16 | static_cast<std::size_t>(p[15]) << 24;
  return std::string_view(bytes).substr(20, length);
}

}  // namespace

Scene import_gltf(const std::string& path, const ImportOptions& options, std::vector<std::array<glm::vec3, 3>>* radiance) {
  const std::string bytes = import::read_file(path, path);
  if (bytes.size() > std::numeric_limits<unsigned int>::max()) fail("{}: file is larger than 2 GiB", path);
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  check_json_depth(json_of(bytes, ext == ".glb"), path);
  // External buffers and images are found in the file's folder (tinygltf wants an absolute one).
  Confinement confinement;
  confinement.folder = std::filesystem::absolute(std::filesystem::path(path)).parent_path().string();
  std::error_code ec;
  confinement.canonical_folder = std::filesystem::canonical(confinement.folder, ec);
  if (ec) fail("{}: cannot resolve its folder ({})", path, ec.message());
  confinement.outside = options.outside_uris;
  tinygltf::TinyGLTF loader;
  loader.SetFsCallbacks({&exists_confined, &tinygltf::ExpandFilePath, &read_confined, &no_write, &confinement});
  loader.SetImageLoader(&load_image_bounded, &confinement);
  tinygltf::Model model;
  std::string err, warn;
  const auto size = static_cast<unsigned int>(bytes.size());
  const std::string& dir = confinement.folder;
  bool ok = ext == ".glb"
                ? loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()), size, dir)
                : loader.LoadASCIIFromString(&model, &err, &warn, bytes.data(), size, dir);
  if (!confinement.refused.empty()) fail("{}: {}", path, confinement.refused);
  auto first_line = [](const std::string& s) {
    const std::string line = s.substr(0, s.find('\n'));
    return import::without_controls(line, 300) + (line.size() > 300 ? "..." : "");
  };
  if (!ok) fail("{}: not a readable glTF file: {}", path, first_line(err.empty() ? warn : err));
  Scene scene = GltfReader(path, model, radiance).read(options);
  if (!warn.empty()) scene.warnings.push_back(fmt::format("{}: {}", path, first_line(warn)));
  return scene;
}

}  // namespace sirad
