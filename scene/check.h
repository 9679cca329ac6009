// sirad: checks of a meshed scene for what will not light as its author meant, before any work:
// objects that look inside out (their faces' fronts see nothing while their backs are enclosed:
// a room made from a cube with its normals out) and emitters that light nothing (a lamp plane
// left facing the ceiling). One-sided faces are sirad's model (DESIGN.md section 1); Cycles
// treats every mesh as two-sided, so a scene from Blender often needs --two-sided.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "scene/mesh.h"
#include "scene/scene.h"

namespace sirad {

// What a run settles and checks about its scene before any work, with one ray scene (Embree)
// for both: the camera of the images, and the warnings to show.
struct SceneCheck {
  std::string camera_from;            // given_by, "the scene's" or "chosen: ..." (how much it sees)
  std::vector<std::string> warnings;  // the importer's notes (Scene::warnings), then one line per
                                      // object that looks inside out and per emitter that lights
                                      // nothing, naming the object (OBJ `o`/`g`) and material
};
// Sets mesh.camera: `camera` if given (camera_from: `given_by`, what gave it), else the scene's,
// else the candidate view (framing the bounding box from outside along each horizontal axis, or from inside it near an
// upper corner looking across) that sees a front face on most of 24 x 24 rays, up +Y, or +Z
// where the emitters face -Z. The orientation checks cast 16 cosine rays from each side of up
// to 20,000 patches. Deterministic.
SceneCheck check_scene(const Scene& scene, PatchMesh& mesh, const std::optional<Camera>& camera,
                       const std::string& given_by = "given");

}  // namespace sirad
