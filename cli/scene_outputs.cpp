// sirad: the scene a command loads and the outputs it writes (see scene_outputs.h).
#include "cli/scene_outputs.h"

#include <cstdio>
#include <filesystem>
#include <new>
#include <optional>

#include <fmt/format.h>

#include "io/results.h"
#include "render/gather.h"
#include "scene/check.h"
#include "util/error.h"

namespace sirad::cli {

void write_outputs(const cli::OutputFlags& o, const std::string& out, const PatchMesh& mesh,
                   const std::vector<glm::vec3>& radiosity, Attributes attrs, const std::string& camera_from,
                   const GatherPasses* gathered, const std::string& image_failed) {
  attrs.emplace_back("sirad.camera_from", camera_from);
  const ResultOptions options = cli::result_options(o);
  // A final gather no cluster rendered: on this machine (its failure keeps the solution, as a
  // cluster's does).
  std::optional<GatherPasses> here;
  std::string why = image_failed;
  if (options.final_gather_spp > 0 && !gathered && why.empty()) {
    try {
      here = FinalGather(mesh, radiosity, final_gather_of(options)).render(*mesh.camera);
      gathered = &*here;
    } catch (const Error& e) {
      why = e.what();
    } catch (const std::bad_alloc&) {
      why = fmt::format("out of memory for a {}x{} image", options.width, options.height);
    }
  }
  ResultFiles files = write_results(out, mesh, radiosity, options, attrs, gathered, why);
  std::printf("camera %s (%s)\n", camera_spec(*mesh.camera).c_str(), camera_from.c_str());
  std::fputs(wrote_lines(files).c_str(), stdout);
}

std::string output_name(const std::string& out, const std::string& scene,
                        std::initializer_list<const char*> extensions) {
  namespace fs = std::filesystem;
  std::string name = out.empty() ? fs::path(scene).stem().string() : out;
  check_output_name(name, "--out");
  std::error_code ec;
  if (fs::is_regular_file(scene, ec))
    for (const char* ext : extensions) {
      fs::path output = name + ext;
      if (fs::exists(output, ec) && fs::equivalent(output, scene, ec))
        fail("{}: the output {} would overwrite the scene file; choose another name with --out", scene, output.string());
    }
  return name;
}

Meshed load_meshed(const std::string& spec, const MeshOptions& mesh_options, const ImportOptions& import,
                   const std::string& camera) {
  std::optional<Camera> given = cli::camera_flag(camera);
  Meshed m;
  m.scene = load_scene(spec, import);
  m.mesh = mesh_scene(m.scene, mesh_options);
  SceneCheck check = check_scene(m.scene, m.mesh, given, "--camera");
  for (const std::string& w : check.warnings) std::fprintf(stderr, "sirad: warning: %s\n", w.c_str());
  m.camera_from = check.camera_from;
  return m;
}

}  // namespace sirad::cli
