// sirad: glTF 2.0 scenes (.gltf, .glb): what is read and how, in core/scene_gltf.cpp.
#pragma once
#include <string>

#include "core/scene.h"

namespace sirad {

// Reads the glTF file `path` into a Scene (its default scene's triangles, materials, objects and
// first perspective camera). Throws sirad::Error naming the file and the element.
Scene import_gltf(const std::string& path, const ImportOptions& options);

}  // namespace sirad
