// sirad: the EXR, PNG and PLY of a solution, written together.
#include "core/results.h"
#include "core/gltf_out.h"
#include "core/scene.h"

#include <algorithm>
#include <filesystem>

#include <unistd.h>

#include "core/error.h"

namespace sirad {

void check_output_name(const std::string& name, const std::string& flag) {
  if (name.empty()) fail("{}: empty output name", flag);
  std::filesystem::path dir = std::filesystem::path(name).parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) fail("{} {}: directory '{}' does not exist", flag, name, dir.string());
  if (::access(dir.c_str(), W_OK) != 0) fail("{} {}: directory '{}' is not writable", flag, name, dir.string());
}

std::string wrote_lines(const ResultFiles& files) {
  std::string out;
  for (const std::string* f : {&files.exr, &files.png, &files.ply, &files.glb})
    out += "wrote " + std::filesystem::absolute(*f).string() + "\n";
  return out;
}

ResultFiles write_results(const std::string& name, const PatchMesh& mesh,
                          const std::vector<glm::vec3>& radiosity, const ResultOptions& options,
                          const Attributes& attributes) {
  if (options.width < 1 || options.height < 1 || options.width > 16384 || options.height > 16384)
    fail("image size {}x{} outside 1..16384", options.width, options.height);
  if (!mesh.camera) fail("{}: the mesh carries no camera", name);
  int s = options.samples_per_side;
  if (s == 0) s = std::clamp(4096 / std::max(options.width, options.height), 1, 4);
  Image image = render_view_antialiased(mesh, radiosity, *mesh.camera, options.width, options.height, options.shading, s);
  ResultFiles files{name + ".exr", name + ".png", name + ".ply", name + ".glb"};
  Attributes with_camera = attributes;
  with_camera.emplace_back("sirad.camera", camera_spec(*mesh.camera));
  write_exr(files.exr, image, with_camera);
  write_png(files.png, image, options.exposure);
  write_ply(files.ply, mesh, radiosity, options.exposure);
  write_glb(files.glb, mesh, radiosity, options.exposure, static_cast<double>(options.width) / options.height);
  return files;
}

}  // namespace sirad
