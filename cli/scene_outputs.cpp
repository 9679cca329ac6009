// sirad: the scene a command loads and the outputs it writes (see scene_outputs.h).
#include "cli/scene_outputs.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <new>
#include <optional>

#include <fmt/format.h>

#include "io/results.h"
#include "io/write_lightmap.h"
#include "render/bake.h"
#include "render/gather.h"
#include "scene/atlas.h"
#include "scene/check.h"
#include "util/error.h"

namespace sirad::cli {

namespace {

// The lightmap of the solution: its atlas, its texels gathered, its files and a line of figures.
void bake(const OutputFlags& o, const std::string& out, const Meshed& m, const std::vector<glm::vec3>& radiosity,
          const Attributes& attrs) {
  const auto start = std::chrono::steady_clock::now();
  Scene faces;
  const Atlas atlas = lightmap_atlas(o.lightmap, m.scene, &faces);
  const FinalGather gather(m.mesh, radiosity, GatherOptions{});
  const Lightmap lightmap = bake_lightmap(faces, atlas, gather, o.lightmap.samples, o.lightmap.lights);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  Attributes a = attrs;
  a.emplace_back("sirad.texel_samples", static_cast<int64_t>(o.lightmap.samples));
  a.emplace_back("sirad.bake_seconds", seconds);
  const LightmapFiles files = write_lightmap(out, faces, atlas, lightmap, o.exposure, m.mesh.camera ? &*m.mesh.camera : nullptr,
                                             static_cast<double>(o.width) / static_cast<double>(std::max(o.height, 1)), a);
  // The texels' relative error: their estimated standard errors over their values, over the
  // texels with light (luminance above 1e-6 of the brightest's): the median, and the RMS of
  // the errors over the RMS of the values (the bright texels weigh as they show).
  auto lum = [](const glm::vec3& v) { return 0.2126 * v.x + 0.7152 * v.y + 0.0722 * v.z; };
  double brightest = 0, errors = 0, values = 0;
  std::vector<double> relative;
  for (const glm::vec3& v : lightmap.combined.pixels) brightest = std::max(brightest, lum(v));
  for (std::size_t k = 0; k < lightmap.combined.pixels.size(); ++k)
    if (const double y = lum(lightmap.combined.pixels[k]); lightmap.coverage[k] > 0 && y > 1e-6 * brightest) {
      const double e = lum(lightmap.error.pixels[k]);
      errors += e * e, values += y * y;
      relative.push_back(e / y);
    }
  const std::size_t lit = relative.size();
  const auto covered = static_cast<double>(std::count_if(lightmap.coverage.begin(), lightmap.coverage.end(), [](float c) { return c > 0; }));
  std::nth_element(relative.begin(), relative.begin() + static_cast<std::ptrdiff_t>(lit / 2), relative.end());
  const double median = lit ? relative[lit / 2] : 0.0, rms = values > 0 ? std::sqrt(errors / values) : 0.0;
  namespace fs = std::filesystem;
  for (const std::string& f : {files.exr, files.png, files.glb}) std::printf("wrote %s\n", fs::absolute(f).c_str());
  std::printf("lightmap %dx%d texels of %.4g (%s), %zu charts (%.0f %% of the atlas), %d samples a texel, %.2f s, "
              "relative error per texel %.3g %% (median; %.3g %% RMS) over %zu lit texels; the indirect light of %.0f %% of "
              "the texels from the cache\n",
              atlas.width, atlas.height, atlas.texel_size, atlas.file_width > 0 ? "the scene's TEXCOORD_1" : "sirad's charts",
              atlas.charts.size(), 100 * atlas.fill(), o.lightmap.samples, seconds,
              100 * median, 100 * rms, lit, covered > 0 ? 100.0 * static_cast<double>(lightmap.cached) / covered : 0.0);
}

}  // namespace

Atlas lightmap_atlas(const LightmapFlags& flags, const Scene& scene, Scene* faces) {
  Scene cut = cut_at_contacts(scene);  // no chart across a wall's foot
  Atlas atlas = make_atlas(cut, {.texel_size = flags.texel_size, .texel_budget = flags.texels, .file_layout = !flags.own_atlas});
  if (atlas.shared_texels > 0)
    std::fprintf(stderr, "warning: %s: %zu lightmap texels lie under more than one island of its TEXCOORD_1 (overlapping UVs): "
                 "each takes the island that covers most of it\n", scene.name.c_str(), atlas.shared_texels);
  if (faces) *faces = std::move(cut);
  return atlas;
}

void write_outputs(const OutputFlags& o, const std::string& out, const Meshed& m, const std::vector<glm::vec3>& radiosity,
                   Attributes attrs, const GatherPasses* gathered, const std::string& image_failed) {
  const PatchMesh& mesh = m.mesh;
  attrs.emplace_back("sirad.camera_from", m.camera_from);
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
  std::printf("camera %s (%s)\n", camera_spec(*mesh.camera).c_str(), m.camera_from.c_str());
  std::fputs(wrote_lines(files).c_str(), stdout);
  if (o.lightmap.on) bake(o, out, m, radiosity, attrs);
}

std::string output_name(const std::string& out, const std::string& scene, const std::vector<std::string>& more) {
  std::vector<std::string> extensions = {".exr", ".png", ".ply", ".glb"};
  extensions.insert(extensions.end(), more.begin(), more.end());
  namespace fs = std::filesystem;
  std::string name = out.empty() ? fs::path(scene).stem().string() : out;
  check_output_name(name, "--out");
  std::error_code ec;
  if (fs::is_regular_file(scene, ec))
    for (const std::string& ext : extensions) {
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
