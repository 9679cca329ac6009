// sirad bench: where a large scene's start-up time and memory go on one node, phase by phase,
// as `sirad render SCENE --patches N` runs them (load, mesh and hash, scene check, kernels,
// first-shot engine, solver set-up with its burn-in, the first counted bundle), then the steady
// cost of a bundle. Prints CSV on stdout:
//   scene,patches,phase,seconds,rss_mib,peak_mib
// one row per phase (seconds of that phase; the process's resident and peak memory after it),
// then `step_median` (seconds of one Solver::step, median of --bundles) and
// `per_patch_bundle_us` (that over the patches, in microseconds); with --shot-blocks, one
// `shot_ms_block_B` row per block size B (0: the whole mesh in one block): the median of 8
// first-shot renders at the run's resolution on an engine of that block size, and the
// process's memory after it.
//   sirad_bench_scale [--scene cornell|FILE] [--patches 20000,100000,400000,1000000] [--bundles 10]
//                     [--shots-per-bundle X] [--shot-blocks 65536,0] [--device D] [--aggregate-nodes N]
// --aggregate-nodes N: then the coordinator's aggregate with N nodes' states of every chunk
// (row `aggregate_N_nodes`: its bytes per patch and node; its memory in rss_mib / peak_mib).
// The settings are `sirad render`'s defaults (chain rule, stratified directions, the auto burn-in
// and grid, 0.25 shots per bundle); each size runs in a fresh child of this program (one
// process per size, so each peak is its own), a single size in this process.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cluster/exchange.h"
#include "cluster/settings.h"
#include "engine/bundle_cl.h"
#include "engine/shot.h"
#include "scene/check.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "solver/solver.h"
#include "util/error.h"

using namespace sirad;
using Clock = std::chrono::steady_clock;

namespace {

// VmRSS and VmHWM of this process, MiB.
std::pair<double, double> memory_mib() {
  std::ifstream in("/proc/self/status");
  double rss = 0, hwm = 0;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("VmRSS:", 0) == 0) rss = std::stod(line.substr(6)) / 1024.0;
    if (line.rfind("VmHWM:", 0) == 0) hwm = std::stod(line.substr(6)) / 1024.0;
  }
  return {rss, hwm};
}

struct Phases {
  std::string scene;
  std::size_t patches = 0;
  Clock::time_point t = Clock::now();
  void row(const char* phase) {
    const auto now = Clock::now();
    const auto [rss, hwm] = memory_mib();
    std::printf("%s,%zu,%s,%.4f,%.1f,%.1f\n", scene.c_str(), patches, phase, std::chrono::duration<double>(now - t).count(), rss,
                hwm);
    std::fflush(stdout);
    t = Clock::now();
  }
};

void run_size(const std::string& spec, std::size_t target, int bundles, double shots_per_bundle,
              const std::vector<std::size_t>& shot_blocks, const std::string& device, uint32_t aggregate_nodes) {
  Phases ph;
  ph.scene = spec;
  Scene scene = load_scene(spec);
  ph.row("load");
  cluster::RunSettings s;
  s.directions = Directions::stratified;
  s.shots_per_bundle = shots_per_bundle;
  s.mesh_options.target_patches = target;
  PatchMesh mesh = mesh_scene(scene, s.mesh_options);
  ph.patches = mesh.size();
  ph.row("mesh_and_hash");
  check_scene(scene, mesh, std::nullopt);
  ph.row("scene_check");
  auto engine = make_cl_engine(mesh, {.device = device});
  ph.row("bundle_engine");
  std::unique_ptr<ShotEngine> shots;
  if (shots_per_bundle > 0) shots = make_cl_shot_engine(mesh, device);
  ph.row("shot_engine");
  SolverOptions so = cluster::solver_options(s, mesh, 0);
  so.track_error = mesh.size() <= kTrackErrorMaxPatches;
  Solver solver(mesh, *engine, so, shots.get());
  ph.row("solver_and_burn_in");
  solver.step(0);
  ph.row("first_bundle");
  std::vector<double> step;
  for (int k = 1; k <= bundles; ++k) {
    auto t0 = Clock::now();
    solver.step(static_cast<uint64_t>(k));
    step.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
  }
  std::sort(step.begin(), step.end());
  const double median = step[step.size() / 2];
  const auto [rss, hwm] = memory_mib();
  std::printf("%s,%zu,step_median,%.4f,%.1f,%.1f\n", spec.c_str(), mesh.size(), median, rss, hwm);
  std::printf("%s,%zu,per_patch_bundle_us,%.4f,%.1f,%.1f\n", spec.c_str(), mesh.size(), 1e6 * median / mesh.size(), rss, hwm);
  std::printf("# %s, %zu patches: grid %d, burn-in %d, shot resolution %d, %.0f bytes per patch at the peak\n", spec.c_str(),
              mesh.size(), solver.grid(), solver.burn_in(), solver.shot_resolution(), hwm * 1048576.0 / mesh.size());
  std::fflush(stdout);
  if (aggregate_nodes > 0) {
    // The coordinator's per-node memory: what its aggregate holds once every one of N nodes has
    // reported every chunk of the run (this node's sums, as each node would send them).
    const auto [rss0, hwm0] = memory_mib();
    const auto starts = cluster::chunk_starts(static_cast<uint32_t>(mesh.size()), cluster::RunSettings{}.chunks);
    cluster::Aggregate aggregate(starts, aggregate_nodes);
    for (uint32_t p = 0; p < aggregate_nodes; ++p)
      for (uint32_t c = 0; c < aggregate.chunks(); ++c) {
        std::vector<double> sum;
        sum.reserve(3 * aggregate.chunk_size(c));
        for (uint32_t j = starts[c]; j < starts[c + 1]; ++j)
          for (int k = 0; k < 3; ++k) sum.push_back(solver.sum()[j][k]);
        aggregate.set(p, c, std::move(sum), solver.bundles());
      }
    const auto [rss1, hwm1] = memory_mib();
    const double per_patch = (rss1 - rss0) * 1048576.0 / static_cast<double>(mesh.size());
    std::printf("%s,%zu,aggregate_%u_nodes,%.1f,%.1f,%.1f\n", spec.c_str(), mesh.size(), aggregate_nodes,
                per_patch / aggregate_nodes, rss1, hwm1);
    std::printf("# the aggregate of %u nodes: %.0f bytes per patch (%.1f per patch and node)\n", aggregate_nodes, per_patch,
                per_patch / aggregate_nodes);
    std::fflush(stdout);
  }
  EmitterTable table = emitter_table(mesh);
  for (std::size_t block : shot_blocks) {
    auto engine = make_cl_shot_engine(mesh, device, block == 0 ? mesh.size() : block);
    std::vector<uint32_t> image;
    std::vector<double> ms;
    for (uint64_t k = 0; k < 9; ++k) {
      SiradShot shot = make_shot(mesh, draw_shot(mesh, table, 1, k), solver.shot_resolution());
      auto t0 = Clock::now();
      engine->render(shot, image);
      if (k > 0) ms.push_back(1e3 * std::chrono::duration<double>(Clock::now() - t0).count());  // the first builds scratch
    }
    std::sort(ms.begin(), ms.end());
    const auto [r, h] = memory_mib();
    std::printf("%s,%zu,shot_ms_block_%zu,%.3f,%.1f,%.1f\n", spec.c_str(), mesh.size(), block, ms[ms.size() / 2], r, h);
    std::fflush(stdout);
  }
}

}  // namespace

int main(int argc, char** argv) {
  try {
    std::string scene = "cornell", device;
    std::vector<std::size_t> sizes = {20000, 100000, 400000, 1000000};
    int bundles = 10;
    std::vector<std::size_t> shot_blocks;
    double shots = 0.25;
    uint32_t aggregate_nodes = 0;
    for (int i = 1; i < argc; ++i) {
      std::string k = argv[i];
      if (i + 1 >= argc) fail("{} needs a value", k);
      std::string v = argv[++i];
      if (k == "--scene") scene = v;
      else if (k == "--patches") {
        sizes.clear();
        std::stringstream ss(v);
        for (std::string n; std::getline(ss, n, ',');) sizes.push_back(std::stoul(n));
      } else if (k == "--bundles") bundles = std::max(1, std::stoi(v));
      else if (k == "--shots-per-bundle") shots = std::stod(v);
      else if (k == "--device") device = v;
      else if (k == "--aggregate-nodes") aggregate_nodes = static_cast<uint32_t>(std::stoul(v));
      else if (k == "--shot-blocks") {
        std::stringstream ss(v);
        for (std::string n; std::getline(ss, n, ',');) shot_blocks.push_back(std::stoul(n));
      }
      else fail("unknown flag {}", k);
    }
    std::printf("scene,patches,phase,seconds,rss_mib,peak_mib\n");
    std::fflush(stdout);
    if (sizes.size() == 1) {  // in this process (for heaptrack and the like)
      run_size(scene, sizes[0], bundles, shots, shot_blocks, device, aggregate_nodes);
      return 0;
    }
    for (std::size_t n : sizes) {
      pid_t pid = fork();
      if (pid < 0) fail("fork: {}", std::strerror(errno));
      if (pid == 0) {
        try {
          run_size(scene, n, bundles, shots, shot_blocks, device, aggregate_nodes);
          std::_Exit(0);
        } catch (const std::exception& e) {
          std::fprintf(stderr, "sirad_bench_scale: %s\n", e.what());
          std::_Exit(1);
        }
      }
      int status = 0;
      waitpid(pid, &status, 0);
      if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) fail("the run at {} patches failed", n);
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad_bench_scale: %s\n", e.what());
    return 1;
  }
}
