// sirad: the EXR, PNG and PLY of a solution, written together.
#include "io/results.h"

#include "io/write_gltf.h"
#include "render/gather.h"
#include "scene/scene.h"
#include "util/check.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <new>
#include <utility>

#include <unistd.h>

#include "util/error.h"

#include <fmt/format.h>

namespace sirad {

void check_output_name(const std::string& name, const std::string& flag) {
  if (name.empty()) fail("{}: empty output name", flag);
  if (std::filesystem::path(name).filename().empty() || name.back() == '/')
    fail("{} {}: names a directory, not an output name (for example {}result)", flag, name, name);
  std::filesystem::path dir = std::filesystem::path(name).parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) fail("{} {}: directory '{}' does not exist", flag, name, dir.string());
  if (::access(dir.c_str(), W_OK) != 0) fail("{} {}: directory '{}' is not writable", flag, name, dir.string());
}

void check_file_name(const std::string& path, const std::string& flag) {
  check_output_name(path, flag);
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) fail("{} {}: is a directory, not a file", flag, path);
}

GatherOptions final_gather_of(const ResultOptions& options) {
  return {.width = options.width, .height = options.height, .spp = options.final_gather_spp};
}

std::string wrote_lines(const ResultFiles& files) {
  std::string out;
  for (const std::string* f : {&files.exr, &files.png, &files.ply, &files.glb})
    out += "wrote " + std::filesystem::absolute(*f).string() + "\n";
  return out;
}

namespace {

// Writes each (path, writer) pair to a temporary beside its path, then replaces the paths only
// once every one is written: all or none (a full disk, a directory in an output's place: no
// mixed set of new and old files is left).
void write_together(const std::vector<std::pair<std::string, std::function<void(const std::string&)>>>& files) {
  namespace fs = std::filesystem;
  const std::string tag = fmt::format(".sirad-{}.tmp", ::getpid());
  std::vector<std::string> temps;
  for (const auto& [path, write] : files) temps.push_back(path + tag);
  try {
    for (const auto& [path, write] : files) {
      std::error_code ec;
      if (fs::is_directory(path, ec)) fail("{}: is a directory; nothing written", path);
    }
    for (std::size_t i = 0; i < files.size(); ++i) files[i].second(temps[i]);
    for (std::size_t i = 0; i < files.size(); ++i)
      if (std::rename(temps[i].c_str(), files[i].first.c_str()) != 0)
        fail("{}: cannot replace it: {}", files[i].first, std::strerror(errno));
  } catch (...) {
    std::error_code ec;
    for (const std::string& t : temps) fs::remove(t, ec);
    throw;
  }
}

}  // namespace

ResultFiles write_results(const std::string& name, const PatchMesh& mesh,
                          const std::vector<glm::vec3>& radiosity, const ResultOptions& options,
                          const Attributes& attributes, const GatherPasses* gathered, const std::string& image_failed) {
  if (options.width < 1 || options.height < 1 || options.width > kMaxImageSide || options.height > kMaxImageSide)
    fail("image size {}x{} outside 1..{}", options.width, options.height, kMaxImageSide);
  if (int64_t{options.width} * options.height > kMaxImagePixels)
    fail("image size {}x{}: more than {} pixels", options.width, options.height, kMaxImagePixels);
  if (!mesh.camera) fail("{}: the mesh carries no camera", name);
  if (radiosity.size() != mesh.size()) fail("{}: {} radiosity values for {} patches", name, radiosity.size(), mesh.size());
  for (std::size_t j = 0; j < radiosity.size(); ++j)
    if (!std::isfinite(radiosity[j].x) || !std::isfinite(radiosity[j].y) || !std::isfinite(radiosity[j].z))
      fail("{}: the result is not finite at patch {} ({}, {}, {}); nothing written", name, j, radiosity[j].x, radiosity[j].y,
           radiosity[j].z);
  const ResultFiles files{name + ".exr", name + ".png", name + ".ply", name + ".glb"};
  double error = -1.0;
  for (const auto& [key, value] : attributes)
    if (key == "sirad.error_estimate" && std::holds_alternative<double>(value)) error = std::get<double>(value);
  const auto ply = [&](const std::string& path) { write_ply(path, mesh, radiosity, options.exposure, error); };
  const auto glb = [&](const std::string& path) {
    write_glb(path, mesh, radiosity, options.exposure, static_cast<double>(options.width) / options.height);
  };
  Attributes with_camera = attributes;
  with_camera.emplace_back("sirad.camera", camera_spec(*mesh.camera));
  GatherPasses passes;
  std::string why = image_failed;
  if (why.empty()) {
    try {
      if (options.final_gather_spp > 0) {
        SIRAD_CHECK(gathered != nullptr, "{}: a final gather's image was asked for and none was given", name);
        if (gathered->combined.width != options.width || gathered->combined.height != options.height)
          fail("a gathered image of {}x{} for {}x{}", gathered->combined.width, gathered->combined.height, options.width,
               options.height);
        passes = *gathered;
      } else {
        int s = options.samples_per_side;
        if (s == 0) s = std::clamp(4096 / std::max(options.width, options.height), 1, 4);
        passes.combined = render_view_antialiased(mesh, radiosity, *mesh.camera, options.width, options.height, options.shading, s);
      }
    } catch (const Error& e) {
      why = e.what();
    } catch (const std::bad_alloc&) {
      why = fmt::format("out of memory for a {}x{} image", options.width, options.height);
    }
  }
  if (!why.empty()) {
    write_together({{files.ply, ply}, {files.glb, glb}});
    fail("{}: no image ({}); the solution is kept in {} and {}", name, why, files.ply, files.glb);
  }
  if (options.final_gather_spp > 0) {
    with_camera.emplace_back("sirad.image", std::string("final gather"));
    with_camera.emplace_back("sirad.spp", static_cast<int64_t>(options.final_gather_spp));
  }
  const Image& image = passes.combined;
  write_together({{files.exr,
                   [&](const std::string& path) {
                     if (options.final_gather_spp > 0)
                       write_exr_layers(path, passes.layers(), with_camera);
                     else
                       write_exr(path, image, with_camera);
                   }},
                  {files.png, [&](const std::string& path) { write_png(path, image, options.exposure); }},
                  {files.ply, ply},
                  {files.glb, glb}});
  return files;
}

}  // namespace sirad
