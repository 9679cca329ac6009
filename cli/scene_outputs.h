// sirad: what the commands of `sirad` that solve or image a scene share: the scene loaded and
// meshed with its camera, the outputs' name checked before any work, and the outputs written
// with their paths on stdout.
#pragma once
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "cli/run_flags.h"
#include "io/write.h"
#include "render/gather.h"
#include "scene/atlas.h"
#include "scene/mesh.h"
#include "scene/scene.h"

namespace sirad::cli {

// The scene `spec` names, meshed, with a camera (the scene's, else a default view of it).
struct Meshed {
  Scene scene;
  PatchMesh mesh;
  std::string camera_from;  // where the camera came from, for the outputs' line and the EXR
};

// The outputs of a solution of `m` and their paths on stdout (`gathered`: the final gather's
// passes a cluster run rendered in tiles, or `image_failed` why it could not, write_results);
// with o.lightmap.on, then the lightmap baked on this machine and its files (io/write_lightmap.h).
void write_outputs(const OutputFlags& o, const std::string& out, const Meshed& m, const std::vector<glm::vec3>& radiosity,
                   Attributes attrs, const GatherPasses* gathered = nullptr, const std::string& image_failed = {});

// The lightmap's atlas of `scene`'s faces cut at their contacts (scene/atlas.h), as `flags`
// ask; sirad::Error for sizes it cannot take (checked before a run, made again after it).
Atlas lightmap_atlas(const LightmapFlags& flags, const Scene& scene, Scene* faces = nullptr);

// The outputs' name: --out, or the scene's file name without extension; checked before any work:
// its folder must be writable, and no output (NAME + .exr, .png, .ply, .glb and each of `more`)
// may be the scene file.
std::string output_name(const std::string& out, const std::string& scene, const std::vector<std::string>& more = {});
// The endings of a lightmap's files (io/write_lightmap.h), for `more` where one is baked.
inline const std::vector<std::string> kLightmapEndings = {"-lightmap.exr", "-lightmap.png", "-baked.glb"};
// The camera: --camera (`camera`, checked first), else the scene's, else one chosen (check_scene).
Meshed load_meshed(const std::string& spec, const MeshOptions& mesh_options, const ImportOptions& import = {},
                   const std::string& camera = "");

}  // namespace sirad::cli
