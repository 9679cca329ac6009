// sirad: `sirad reference`, `sirad image`, `sirad devices` and `sirad keygen` (see commands.h).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>

#include "cli/commands.h"
#include "cli/scene_outputs.h"
#include "engine/opencl.h"
#include "engine/version.h"
#include "io/read_solution.h"
#include "io/results.h"
#include "io/write.h"
#include "proto/security.h"
#include "solver/metrics.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace sirad::cli {
namespace {

// The views of a --cameras file: one per line, each named by its line in errors.
std::vector<Camera> read_cameras(const std::string& path) {
  const std::string text = read_file_whole(path, "cameras file", std::size_t{1} << 24);
  std::vector<Camera> out;
  std::size_t at = 0;
  for (int line = 1; at <= text.size(); ++line) {
    std::size_t end = text.find('\n', at);
    if (end == std::string::npos) end = text.size();
    std::string l = text.substr(at, end - at);
    at = end + 1;
    const std::size_t first = l.find_first_not_of(" \t\r");
    if (first == std::string::npos || l[first] == '#') continue;
    if (out.size() >= 100000) fail("{}: more than 100000 views", path);
    try {
      out.push_back(parse_camera(l));
    } catch (const Error& e) {
      fail("{}: line {}: {}", path, line, e.what());
    }
  }
  if (out.empty()) fail("{}: no view in it", path);
  return out;
}

}  // namespace

int reference(const ReferenceArgs& r) {
  MeshOptions mesh_options = mesh_options_from(r.mesh, r.given);
  if (r.options.rays_per_patch < r.options.batches)
    fail("--rays {} is below --batches {}", r.options.rays_per_patch, r.options.batches);
  if (r.options.light_samples < r.options.batches)
    fail("--light-samples {} is below --batches {}", r.options.light_samples, r.options.batches);
  std::string out = output_name(r.output.out, r.scene, {".ref.csv"});
  const Meshed m = load_meshed(r.scene, mesh_options, r.output.import(), r.output.camera);
  const PatchMesh& mesh = m.mesh;
  cli::OutputFlags output = r.output;
  cli::settle_image_size(output, m.scene);
  if (!r.quiet)
    std::fprintf(stderr, "sirad: %s: %zu patches, reference with %d rays and %d light samples per patch, %d batches\n",
                 r.scene.c_str(), mesh.size(), r.options.rays_per_patch, r.options.light_samples, r.options.batches);
  ReferenceSolution s = solve_reference(mesh, r.options);
  std::vector<glm::vec3> radiosity(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) radiosity[j] = glm::vec3(s.radiosity[j]);
  // Its own expected relative RMS error per patch, in the measure of the bundle solver's estimate
  // (solver/metrics.h): its PLY carries it, so a reference can start a warm run.
  const double error = relative_rms_vs_reference(mesh, radiosity, s.radiosity, s.radiosity_se).ref_share;
  Attributes attrs = {
      {"sirad.version", std::string(kVersion)},
      {"sirad.scene", r.scene},
      {"sirad.scene_hash", mesh.hash},
      {"sirad.patches", static_cast<int64_t>(mesh.size())},
      {"sirad.solver", std::string("reference")},
      {"sirad.rays_per_patch", static_cast<int64_t>(r.options.rays_per_patch)},
      {"sirad.light_samples", static_cast<int64_t>(r.options.light_samples)},
      {"sirad.batches", static_cast<int64_t>(r.options.batches)},
      {"sirad.seed", std::to_string(r.options.seed)},
      {"sirad.error_estimate", error},
  };
  write_outputs(output, out, m, radiosity, attrs);
  const std::string csv = out + ".ref.csv";
  write_reference(csv, mesh, s, r.options);
  std::printf("wrote %s\n", std::filesystem::absolute(csv).c_str());
  std::printf("patches %zu, rays %llu, %.2f s, %.3g rays/s, %d sweeps%s, mean relative SE %.3g%%, relative RMS SE %.3g%%\n",
              mesh.size(), static_cast<unsigned long long>(s.rays), s.seconds, static_cast<double>(s.rays) / s.seconds,
              s.iterations, s.converged ? "" : " (not converged: iteration cap)", 100.0 * mean_relative_se(mesh, s),
              100.0 * error);
  return 0;
}

int image(ImageArgs& a) {
  namespace fs = std::filesystem;
  const std::string name = a.out.empty() ? fs::path(a.solution).stem().string() + "-image" : a.out;
  check_output_name(name, "--out");
  Solution s = read_solution(a.solution);
  cli::settle_image_size(a.gather.width, a.gather.height, a.camera.empty() && a.cameras.empty() ? s.camera_aspect : std::nullopt);
  const FinalGather gather(s.mesh, std::move(s.corners), a.gather);  // the scene's rays made once, for every view
  std::vector<Camera> views;
  if (!a.cameras.empty()) views = read_cameras(a.cameras);
  else if (!a.camera.empty()) views = {cli::camera_flag(a.camera).value()};
  else if (s.mesh.camera) views = {*s.mesh.camera};
  else fail("{}: the solution names no camera: give --camera", a.solution);
  for (std::size_t v = 0; v < views.size(); ++v) {
    const std::string out = views.size() == 1 ? name : fmt::format("{}-{:04}", name, v + 1);
    for (const char* ext : {".exr", ".png"})
      if (std::error_code ec; fs::exists(out + ext, ec) && fs::equivalent(out + ext, a.solution, ec))
        fail("{}: the output {}{} would overwrite the solution; choose another name with --out", a.solution, out, ext);
    const auto start = std::chrono::steady_clock::now();
    GatherPasses p = gather.render(views[v]);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const Attributes attrs = {{"sirad.version", std::string(kVersion)},
                              {"sirad.solution", a.solution},
                              {"sirad.patches", static_cast<int64_t>(s.mesh.size())},
                              {"sirad.image", std::string("final gather")},
                              {"sirad.spp", static_cast<int64_t>(a.gather.spp)},
                              {"sirad.seed", std::to_string(a.gather.seed)},
                              {"sirad.camera", camera_spec(views[v])},
                              {"sirad.seconds", seconds}};
    write_exr_layers(out + ".exr", p.layers(), attrs);
    write_png(out + ".png", p.combined, a.exposure);
    std::printf("wrote %s\nwrote %s\n", fs::absolute(out + ".exr").c_str(), fs::absolute(out + ".png").c_str());
    if (!a.quiet)
      std::printf("%dx%d, %d spp, %zu patches, %.2f s, %.3g rays/s (%.0f %% of them for the cache)\n", a.gather.width, a.gather.height,
                  a.gather.spp, s.mesh.size(), seconds, static_cast<double>(p.rays + p.record_rays) / std::max(seconds, 1e-9),
                  100.0 * static_cast<double>(p.record_rays) / std::max<double>(1.0, static_cast<double>(p.rays + p.record_rays)));
  }
  return 0;
}

int devices() {
  for (const auto& d : list_devices())
    std::printf("%d:%d  %s / %s  (%s, %u compute units)\n", d.platform, d.device, d.platform_name.c_str(),
                d.device_name.c_str(), d.version.c_str(), d.compute_units);
  return 0;
}

int keygen(const std::string& name) {
  check_output_name(name, "keygen NAME");
  proto::KeyPair keys = proto::generate_keypair();
  proto::write_keypair(name, keys);
  std::printf("wrote %s.key\nwrote %s.key_secret (mode 0600; keep it on this machine)\n"
              "allow-list line: %s %s\n",
              name.c_str(), name.c_str(), keys.public_key.c_str(), std::filesystem::path(name).filename().c_str());
  return 0;
}

}  // namespace sirad::cli
