// sirad bench: milliseconds per bundle and line crossings per second of the OpenCL kernels and
// of the C++ reference, measured in the same run, on the Cornell box; then the relative RMS
// difference between two independent runs against bundles. Prints CSV on stdout.
//   sirad_bench_bundle [--patches N] [--grids 256,512,1024] [--bundles K] [--reference-bundles K]
//                      [--error-bundles K] [--auto-patches 5000,20000] [--device D] [--paths band,wide]
//                      [--batches 1,8,32]
// --paths: the transfer paths to time (engine/bundle_cl.h), each a row `opencl-PATH`; without
// it the device's own choice, rows `opencl`. --batches: bundles per run_batch at the fixed grids
// (rows `opencl-PATH-xB` for B > 1; the band path runs a batch's bundles in turn).
// --grids none skips the fixed grids; --reference-bundles 0 skips the reference.
// --auto-patches: for each size, the Cornell box at that size and its auto grid (auto_grid, as
// `sirad render cornell --patches N` uses): the engine alone (engine_auto) and one whole
// Solver::step on it (solver_auto: host work per bundle included), medians over --bundles.
// Columns: median and least wall ms per bundle, crossings per second, and the process's CPU ms
// per bundle (all threads; on a busy machine the steadier measure of work done).
#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <cmath>
#include <cstring>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "engine/bundle_cl.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "solver/metrics.h"
#include "solver/solver.h"
#include "util/error.h"

using namespace sirad;

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// CPU time of the whole process (host thread and the OpenCL runtime's threads), seconds: less
// sensitive than wall time to other work on a shared machine (it misses idle waits).
double cpu_seconds() {
  timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

struct Timing {
  double median_ms = 0, min_ms = 0, cpu_ms = 0;  // per bundle; cpu_ms: the mean
  double crossings_per_s = 0;
};

// Per bundle over `bundles` bundles (after one warm-up), run `batch` at a time (run_batch):
// median and least wall ms of a batch over its bundles, mean CPU ms, and crossings per second
// of wall time.
Timing time_engine(const PatchMesh& mesh, BundleEngine& engine, int grid, int bundles, int batch = 1) {
  std::vector<glm::vec4> radiance(mesh.size(), glm::vec4(1.0f));
  std::vector<BundleResult> r(static_cast<std::size_t>(batch));
  std::vector<SiradBundle> b(static_cast<std::size_t>(batch));
  for (int i = 0; i < batch; ++i) b[static_cast<std::size_t>(i)] = make_bundle(mesh, grid, 1, 1000000 + static_cast<uint64_t>(i));
  engine.run_batch(b, radiance, r);
  std::vector<double> ms;
  uint64_t crossings = 0;
  double total = 0, cpu0 = cpu_seconds();
  const int batches = std::max(1, bundles / batch);
  for (int k = 0; k < batches; ++k) {
    for (int i = 0; i < batch; ++i)
      b[static_cast<std::size_t>(i)] = make_bundle(mesh, grid, 1, static_cast<uint64_t>(k * batch + i));
    auto t0 = std::chrono::steady_clock::now();
    engine.run_batch(b, radiance, r);
    double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ms.push_back(1e3 * s / batch);
    total += s;
    for (const BundleResult& x : r) crossings += x.crossings;
  }
  double cpu = cpu_seconds() - cpu0;
  return {median(ms), *std::min_element(ms.begin(), ms.end()), 1e3 * cpu / (batches * batch), crossings / total};
}

// One Solver::step (chain rule, no burn-in) after one warm-up step, as time_engine.
Timing time_solver(const PatchMesh& mesh, BundleEngine& engine, int bundles) {
  Solver solver(mesh, engine, {.seed = 1, .burn_in = 0});
  solver.step(0);
  std::vector<double> ms;
  double cpu0 = cpu_seconds();
  for (int k = 1; k <= bundles; ++k) {
    auto t0 = std::chrono::steady_clock::now();
    solver.step(static_cast<uint64_t>(k));
    ms.push_back(1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  double cpu = cpu_seconds() - cpu0;
  return {median(ms), *std::min_element(ms.begin(), ms.end()), 1e3 * cpu / bundles, 0};
}

void print_row(const char* engine, int grid, std::size_t patches, const Timing& t) {
  std::printf("%s,%d,%zu,%.3f,%.4g,%.3f,%.3f\n", engine, grid, patches, t.median_ms, t.crossings_per_s, t.min_ms,
              t.cpu_ms);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    std::size_t patches = 20000;
    std::vector<int> grids = {256, 512, 1024};
    std::vector<std::size_t> auto_patches;
    int bundles = 30, ref_bundles = 3, error_bundles = 1024;
    std::string device;
    std::vector<std::optional<TransferPath>> paths = {std::nullopt};
    std::vector<int> batch_sizes = {1};
    for (int i = 1; i + 1 < argc; i += 2) {
      std::string k = argv[i], v = argv[i + 1];
      if (k == "--patches") patches = std::stoul(v);
      else if (k == "--bundles") bundles = std::stoi(v);
      else if (k == "--reference-bundles") ref_bundles = std::stoi(v);
      else if (k == "--error-bundles") error_bundles = std::stoi(v);
      else if (k == "--device") device = v;
      else if (k == "--batches") {
        batch_sizes.clear();
        std::stringstream ss(v);
        for (std::string g; std::getline(ss, g, ',');) batch_sizes.push_back(std::max(1, std::stoi(g)));
      } else if (k == "--paths") {
        paths.clear();
        std::stringstream ss(v);
        for (std::string g; std::getline(ss, g, ',');) paths.push_back(parse_transfer_path(g));
      }
      else if (k == "--grids") {
        grids.clear();
        std::stringstream ss(v);
        if (v != "none")
          for (std::string g; std::getline(ss, g, ',');) grids.push_back(std::stoi(g));
      } else if (k == "--auto-patches") {
        std::stringstream ss(v);
        for (std::string g; std::getline(ss, g, ',');) auto_patches.push_back(std::stoul(g));
      } else fail("unknown flag {}", k);
    }
    PatchMesh mesh = mesh_scene(builtin_cornell(), {.target_patches = patches});
    std::vector<std::unique_ptr<BundleEngine>> engines;
    std::vector<std::string> names;
    for (const auto& path : paths) {
      engines.push_back(make_cl_engine(mesh, {.device = device, .path = path}));
      names.push_back(path ? std::string("opencl-") + to_string(*path) : "opencl");
    }
    auto& cl = engines.front();
    auto ref = make_reference_engine(mesh);
    std::printf("# device: %s; cornell, %zu patches\n", cl->description().c_str(), mesh.size());
    std::printf("engine,grid,patches,ms_per_bundle_median,crossings_per_s,ms_per_bundle_min,cpu_ms_per_bundle\n");
    for (int grid : grids) {
      for (std::size_t e = 0; e < engines.size(); ++e)
        for (int batch : batch_sizes) {
          const std::string name = batch > 1 ? names[e] + "-x" + std::to_string(batch) : names[e];
          print_row(name.c_str(), grid, mesh.size(), time_engine(mesh, *engines[e], grid, std::max(bundles, batch), batch));
        }
      if (ref_bundles > 0) print_row("reference", grid, mesh.size(), time_engine(mesh, *ref, grid, ref_bundles));
      std::fflush(stdout);
    }
    for (std::size_t target : auto_patches) {
      PatchMesh m = mesh_scene(builtin_cornell(), {.target_patches = target});
      for (const auto& path : paths) {
        auto engine = make_cl_engine(m, {.device = device, .path = path});
        int grid = auto_grid(m);
        const std::string suffix = path ? std::string("-") + to_string(*path) : "";
        print_row(("engine_auto" + suffix).c_str(), grid, m.size(), time_engine(m, *engine, grid, bundles));
        print_row(("solver_auto" + suffix).c_str(), grid, m.size(), time_solver(m, *engine, bundles));
        std::fflush(stdout);
      }
    }
    if (error_bundles > 0) {
      // Relative RMS difference of two independent runs, divided by sqrt(2): the error of one.
      std::printf("\nbundles,relative_rms_error_per_patch\n");
      Solver a(mesh, *cl, {.seed = 1}), b(mesh, *cl, {.seed = 2});
      for (int k = 0; k < error_bundles; ++k) {
        a.step(k);
        b.step(k);
        if (((k + 1) & k) == 0 && k + 1 >= 16)
          std::printf("%d,%.5f\n", k + 1, relative_rms(mesh, a.estimate(), b.estimate()) / std::sqrt(2.0));
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad_bench_bundle: error: %s\n", e.what());
    return 1;
  }
}
