// sirad: PLY scenes (.ply, ascii or binary): what is read and how, in scene/ply.cpp.
#pragma once
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "scene/scene.h"

namespace sirad {

// Reads the PLY file `path` into a Scene (one object named after the file). Throws sirad::Error
// naming the file and the element. The comments `sirad camera SPEC` and `sirad background R G B`
// (sirad's own PLY) give the scene's camera and background. `radiosity`, if given, gets each
// triangle's float face properties radiosity_r/g/b (a solution's PLY); a file without them is refused.
// `error_estimate`, if given, gets the comment `sirad error estimate E` (the run's), or -1.
Scene import_ply(const std::string& path, const ImportOptions& options, std::vector<glm::vec3>* radiosity = nullptr,
                 double* error_estimate = nullptr);

}  // namespace sirad
