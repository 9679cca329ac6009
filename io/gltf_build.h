// sirad: the parts io/'s glTF writers share (write_gltf.cpp, write_lightmap.cpp): accessors in
// the one buffer, numbers as JSON, the camera node of a view, the file written atomically.
// Included by io/'s .cpp files only (it brings tinygltf).
#pragma once
#include <tiny_gltf.h>

#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "scene/scene.h"

namespace sirad::gltf {

// Appends `size` bytes to buffer 0 (at a multiple of 4) as a buffer view of `target` (0: none,
// as for an image); returns its index.
int add_view(tinygltf::Model& m, const void* bytes, std::size_t size, int target);

// Appends `values` to buffer 0 as an accessor of `count` elements of `type` (float or uint32
// components), in a view of its own of `target`; returns its index.
template <typename T>
int add_accessor(tinygltf::Model& m, const std::vector<T>& values, std::size_t count, int type, int component, int target) {
  tinygltf::Accessor a;
  a.bufferView = add_view(m, values.data(), values.size() * sizeof(T), target);
  a.byteOffset = 0;
  a.componentType = component;
  a.count = count;
  a.type = type;
  m.accessors.push_back(a);
  return static_cast<int>(m.accessors.size() - 1);
}

// Vertex attributes of values.size() / 3 (VEC3) or / 2 (VEC2) vertices, float, in an array
// buffer; POSITION's carries the min and max glTF requires of it.
int add_vec3(tinygltf::Model& m, const std::vector<float>& values);
int add_positions(tinygltf::Model& m, const std::vector<float>& values);
int add_vec2(tinygltf::Model& m, const std::vector<float>& values);
// Triangle indices, uint32, in an element array buffer.
int add_indices(tinygltf::Model& m, const std::vector<uint32_t>& indices);
// `mesh` into the model, with a node of its name in `scene`.
void add_mesh(tinygltf::Model& m, tinygltf::Scene& scene, tinygltf::Mesh mesh);

// Three numbers as a JSON array (a float is a double exactly: read back, the same float).
tinygltf::Value triple(const glm::vec3& v);

// A camera node for `camera` (eye, looking along the node's -Z, +Y up; sirad_camera in its
// extras: the view exactly), near and far planes around a scene of that centre and radius,
// added to `scene`.
void add_camera(tinygltf::Model& m, tinygltf::Scene& scene, const Camera& camera, const glm::vec3& centre, float radius,
                double aspect);

// `m` with `scene` as its only scene, as binary glTF at `path`, atomically.
void save_glb(tinygltf::Model& m, tinygltf::Scene scene, const std::string& path);

}  // namespace sirad::gltf
