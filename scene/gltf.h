// sirad: glTF 2.0 scenes (.gltf, .glb): what is read and how, in scene/gltf.cpp.
#pragma once
#include <array>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "scene/scene.h"

namespace sirad {

// Reads the glTF file `path` into a Scene (its default scene's triangles, materials, objects and
// first perspective camera). Throws sirad::Error naming the file and the element. A file sirad
// wrote (io/write_gltf.h) gives its scene's reflectance, emission, camera and background from
// its extras. `radiance`, if given, gets per triangle (in the Scene's order) the _RADIANCE of
// its three corners: the solution itself; a primitive without it is refused.
Scene import_gltf(const std::string& path, const ImportOptions& options, std::vector<std::array<glm::vec3, 3>>* radiance = nullptr);

}  // namespace sirad
