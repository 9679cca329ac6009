// sirad: NAME.glb, the solution as binary glTF 2.0 for any viewer and for Blender's importer.
// One mesh per object of the input (its name kept), one primitive per material; per vertex
// COLOR_0 = the radiance times 2^exposure clamped to [0, 1] (linear, as glTF's colours are) and
// _RADIANCE = the radiance itself (float, unclamped); a vertex is shared only by the corners
// corner_radiosity gives one value (one smooth surface of one material), so creases and material
// borders stay sharp. Materials are KHR_materials_unlit with a white base colour: viewers show
// the lighting as solved. Back faces stay one-sided (doubleSided false), as the solution is; a
// two-sided surface carries both sides as two faces, pulled kSidesApart of the scene's radius
// apart along their normals (Cycles ignores back-face culling: at one place it would show either). The camera of the images is a camera node.
// What a viewer has no use for, but rendering from the file again needs (io/read_solution.h), is
// in `extras`: each material's sirad_reflectance and sirad_emission, the camera node's
// sirad_camera (camera_spec: the view exactly, not rebuilt from the node's matrix) and the
// asset's sirad_background. _RADIANCE holds the interpolated solution itself.
#pragma once
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "io/write.h"
#include "scene/mesh.h"

namespace sirad {

inline constexpr double kSidesApart = 1e-4;

// Writes `path` atomically. `aspect`: the images' width / height (the camera's aspect ratio).
void write_glb(const std::string& path, const PatchMesh& mesh, const std::vector<glm::vec3>& radiosity,
               float exposure, double aspect);

}  // namespace sirad
