// sirad: checks of a meshed scene for what will not light as its author meant, before any work:
// objects that look inside out (their faces' fronts see nothing while their backs are enclosed:
// a room made from a cube with its normals out) and emitters that light nothing (a lamp plane
// left facing the ceiling). One-sided faces are sirad's model (DESIGN.md section 1); Cycles
// treats every mesh as two-sided, so a scene from Blender often needs --two-sided.
#pragma once
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/scene.h"

namespace sirad {

// One line per problem, naming the object (OBJ `o`/`g`) and material. A few cosine rays from
// both sides of (a sample of) the patches, cast with Embree; deterministic.
std::vector<std::string> orientation_warnings(const Scene& scene, const PatchMesh& mesh);

// A camera for a scene that carries none: of a few candidate views (framing the bounding box
// from outside along each horizontal axis, and from inside it near each upper corner looking
// across), the one whose view sees a front face on the most of 24 x 24 rays. Up is +Y, or +Z
// where the emitters face -Z (a Z-up export with ceiling lamps). `seen` (optional): that share.
Camera choose_camera(const Scene& scene, const PatchMesh& mesh, double* seen = nullptr);

// Everything to warn about before a run: the importer's notes (Scene::warnings) and the above.
std::vector<std::string> scene_warnings(const Scene& scene, const PatchMesh& mesh);

}  // namespace sirad
