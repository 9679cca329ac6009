// sirad: PLY scenes (.ply, ascii or binary): what is read and how, in core/scene_ply.cpp.
#pragma once
#include <string>

#include "core/scene.h"

namespace sirad {

// Reads the PLY file `path` into a Scene (one object named after the file). Throws sirad::Error
// naming the file and the element.
Scene import_ply(const std::string& path, const ImportOptions& options);

}  // namespace sirad
