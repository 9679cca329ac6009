// sirad: the parts io/'s glTF writers share (see gltf_build.h).
#include "io/gltf_build.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <glm/geometric.hpp>

#include "util/atomic_file.h"
#include "util/error.h"

namespace sirad::gltf {

int add_view(tinygltf::Model& m, const void* bytes, std::size_t size, int target) {
  auto& data = m.buffers[0].data;
  while (data.size() % 4 != 0) data.push_back(0);
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = data.size();
  view.byteLength = size;
  view.target = target;
  const auto* begin = static_cast<const unsigned char*>(bytes);
  data.insert(data.end(), begin, begin + size);
  m.bufferViews.push_back(view);
  return static_cast<int>(m.bufferViews.size() - 1);
}

int add_vec3(tinygltf::Model& m, const std::vector<float>& values) {
  return add_accessor(m, values, values.size() / 3, TINYGLTF_TYPE_VEC3, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TARGET_ARRAY_BUFFER);
}

int add_positions(tinygltf::Model& m, const std::vector<float>& values) {
  const int index = add_vec3(m, values);
  std::vector<double> lo(3, 1e300), hi(3, -1e300);
  for (std::size_t i = 0; i < values.size(); ++i)
    lo[i % 3] = std::min(lo[i % 3], static_cast<double>(values[i])), hi[i % 3] = std::max(hi[i % 3], static_cast<double>(values[i]));
  m.accessors.back().minValues = lo;
  m.accessors.back().maxValues = hi;
  return index;
}

int add_vec2(tinygltf::Model& m, const std::vector<float>& values) {
  return add_accessor(m, values, values.size() / 2, TINYGLTF_TYPE_VEC2, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TARGET_ARRAY_BUFFER);
}

int add_indices(tinygltf::Model& m, const std::vector<uint32_t>& indices) {
  return add_accessor(m, indices, indices.size(), TINYGLTF_TYPE_SCALAR, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                      TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
}

void add_mesh(tinygltf::Model& m, tinygltf::Scene& scene, tinygltf::Mesh mesh) {
  tinygltf::Node node;
  node.name = mesh.name;
  m.meshes.push_back(std::move(mesh));
  node.mesh = static_cast<int>(m.meshes.size() - 1);
  m.nodes.push_back(node);
  scene.nodes.push_back(static_cast<int>(m.nodes.size() - 1));
}

tinygltf::Value triple(const glm::vec3& v) {
  return tinygltf::Value(tinygltf::Value::Array{tinygltf::Value(static_cast<double>(v.x)), tinygltf::Value(static_cast<double>(v.y)),
                                                tinygltf::Value(static_cast<double>(v.z))});
}

void add_camera(tinygltf::Model& m, tinygltf::Scene& scene, const Camera& camera, const glm::vec3& centre, float radius,
                double aspect) {
  const glm::dvec3 eye(camera.eye), f = glm::normalize(glm::dvec3(camera.look_at) - eye);
  const glm::dvec3 r = glm::normalize(glm::cross(f, glm::dvec3(camera.up))), u = glm::cross(r, f);
  tinygltf::Camera cam;
  cam.type = "perspective";
  cam.name = "sirad view";
  cam.perspective.yfov = camera.vfov_deg * 3.14159265358979323846 / 180.0;
  const double reach = static_cast<double>(radius) + glm::length(glm::dvec3(centre) - eye);
  cam.perspective.znear = 1e-3 * std::max(static_cast<double>(radius), 1e-6);
  cam.perspective.zfar = std::max(10.0 * reach, 2.0 * cam.perspective.znear);  // beyond the whole scene
  cam.perspective.aspectRatio = aspect > 0.0 && std::isfinite(aspect) ? aspect : 1.0;
  m.cameras.push_back(cam);
  tinygltf::Node node;
  node.name = "sirad view";
  node.camera = static_cast<int>(m.cameras.size() - 1);
  node.extras = tinygltf::Value(tinygltf::Value::Object{{"sirad_camera", tinygltf::Value(camera_spec(camera))}});
  node.matrix = {r.x, r.y, r.z, 0, u.x, u.y, u.z, 0, -f.x, -f.y, -f.z, 0, eye.x, eye.y, eye.z, 1};
  m.nodes.push_back(node);
  scene.nodes.push_back(static_cast<int>(m.nodes.size() - 1));
}

void save_glb(tinygltf::Model& m, tinygltf::Scene scene, const std::string& path) {
  m.buffers[0].data.resize((m.buffers[0].data.size() + 3) / 4 * 4, 0);
  m.scenes.push_back(std::move(scene));
  m.defaultScene = 0;
  std::ostringstream out;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&m, out, false, true)) fail("cannot write {}: the glTF writer failed", path);
  const std::string bytes = out.str();
  AtomicFile file(path);
  file.write(bytes.data(), bytes.size());
  file.commit();
}

}  // namespace sirad::gltf
