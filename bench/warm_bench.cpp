// sirad bench: a rebake after an edit (--warm-start, solver/warm_start.h) against a cold start,
// to the same target error. Solves the scene as it was (the previous run: P and its own error
// estimate, --previous-bundles), moves the named objects by --move DX DY DZ, solves the scene after
// by a long cold run (the reference, --reference-bundles: its own error estimate is taken out of
// the measured errors), then --reps times a cold run (the command line's defaults: stratified
// directions, 0.25 shots a bundle) and a warm run from P, each until its error estimate is ready
// and at or below --target (as --target-error stops a run). CSV per run: mode, rep, bundles,
// seconds (the warm run's set-up of the old patches' engine and the match counted), the run's
// estimate, the measured relative RMS error per non-emitting patch (solver/metrics.h, the
// reference's error subtracted in quadrature) and the area-weighted mean over non-emitting
// patches against the reference's. Then the medians and their ratio.
//
//   sirad_bench_warm --scene tests/data/blender/apartment.obj --two-sided --objects SofaSeat,SofaBack
//       --move 0.3 0 0 --patches 20000
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "cluster/settings.h"
#include "engine/bundle_cl.h"
#include "engine/shot.h"
#include "scene/scene.h"
#include "solver/metrics.h"
#include "solver/solver.h"
#include "solver/warm_start.h"
#include "util/error.h"

using namespace sirad;

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Runs `solver` from bundle 0 until its estimate is ready and at or below `target`, or `cap` bundles.
uint64_t run_to(Solver& solver, double target, uint64_t cap) {
  uint64_t k = 0;
  while (k < cap) {
    solver.step(k++);
    if (target > 0 && solver.error_estimate_ready() && solver.error_estimate() <= target) break;
  }
  return k;
}

double mean_ratio(const PatchMesh& mesh, const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b) {
  double sa = 0, sb = 0;
  for (std::size_t j = 0; j < mesh.size(); ++j) {
    if (mesh.emits(j)) continue;
    sa += mesh.area[j] * (a[j].x + a[j].y + a[j].z);
    sb += mesh.area[j] * (b[j].x + b[j].y + b[j].z);
  }
  return sa / sb;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v.size() % 2 ? v[v.size() / 2] : (v[v.size() / 2 - 1] + v[v.size() / 2]) / 2.0;
}

}  // namespace

int main(int argc, char** argv) try {
  CLI::App app{"sirad bench: a warm start after an edit against a cold start, to one target error (CSV)"};
  std::string scene_path, objects;
  std::vector<float> move{0.3f, 0.0f, 0.0f};
  int patches = 20000, reps = 3;
  uint64_t previous_bundles = 8000, reference_bundles = 32000, cap = 100000;
  double target = 0.02;
  bool two_sided = false;
  app.add_option("--scene", scene_path, "Scene file")->required();
  app.add_option("--objects", objects, "Objects to move, comma-separated (OBJ o names)")->required();
  app.add_option("--move", move, "The move: DX DY DZ")->expected(3);
  app.add_option("--patches", patches, "Patches");
  app.add_option("--previous-bundles", previous_bundles, "Bundles of the previous run (before the edit)");
  app.add_option("--reference-bundles", reference_bundles, "Bundles of the cold reference after the edit");
  app.add_option("--target", target, "Target error of the cold and warm runs");
  app.add_option("--reps", reps, "Cold and warm runs each");
  app.add_flag("--two-sided", two_sided, "Every surface two-sided (as sirad render --two-sided)");
  CLI11_PARSE(app, argc, argv);

  const Scene before_scene = load_scene(scene_path, {.two_sided = two_sided});
  Scene after_scene = before_scene;
  std::set<std::string> moved;
  for (std::stringstream in(objects); in.good();) {
    std::string name;
    std::getline(in, name, ',');
    moved.insert(name);
  }
  std::size_t moved_triangles = 0;
  for (Triangle& t : after_scene.triangles)
    if (t.object < after_scene.objects.size() && moved.count(after_scene.objects[t.object])) {
      for (glm::vec3& p : t.p) p += glm::vec3(move[0], move[1], move[2]);
      ++moved_triangles;
    }
  if (moved_triangles == 0) fail("no triangle of the objects {}", objects);

  const MeshOptions meshing{.target_patches = static_cast<std::size_t>(patches)};
  PatchMesh before = mesh_scene(before_scene, meshing);
  const cluster::RunSettings defaults;
  std::fprintf(stderr, "previous run: %llu bundles on %zu patches\n", static_cast<unsigned long long>(previous_bundles), before.size());
  std::vector<glm::vec3> p;
  double p_error = 0;
  {
    auto engine = make_cl_engine(before);
    auto shots = make_cl_shot_engine(before);
    SolverOptions so = cluster::solver_options(defaults, before, 0);
    so.track_error = true;
    Solver s(before, *engine, so, shots.get());
    run_to(s, 0.0, previous_bundles);
    p = s.estimate();
    p_error = s.error_estimate();
  }
  const PatchMesh after_alone = mesh_scene(after_scene, meshing);
  std::fprintf(stderr, "reference: %llu bundles on %zu patches\n", static_cast<unsigned long long>(reference_bundles), after_alone.size());
  std::vector<glm::vec3> ref;
  double ref_error = 0;
  {
    auto engine = make_cl_engine(after_alone);
    SolverOptions so = cluster::solver_options(defaults, after_alone, 0);
    so.seed = 1000003;
    so.shots_per_bundle = 0;
    so.track_error = true;
    Solver s(after_alone, *engine, so);
    run_to(s, 0.0, reference_bundles);
    ref = s.estimate();
    ref_error = s.error_estimate();
  }
  auto measured = [&](const std::vector<glm::vec3>& x) {
    const double raw = relative_rms(after_alone, x, ref);
    return std::sqrt(std::max(raw * raw - ref_error * ref_error, 0.0));
  };
  std::printf("# previous error %.5f, reference error %.5f, %zu triangles moved by (%g, %g, %g)\n", p_error, ref_error,
              moved_triangles, move[0], move[1], move[2]);
  std::printf("mode,rep,bundles,seconds,estimate,measured,mean\n");
  std::vector<double> times[2];
  for (int rep = 0; rep < reps; ++rep) {
    for (int warm = 0; warm < 2; ++warm) {
      const auto t0 = Clock::now();
      PatchMesh mesh = after_alone;
      PatchMesh old = before;
      std::unique_ptr<BundleEngine> old_engine;
      WarmStart w;
      SolverOptions so = cluster::solver_options(defaults, mesh, 0);
      so.seed = 11 + static_cast<uint64_t>(rep);
      so.track_error = true;
      if (warm) {
        share_bound(mesh, old);
        old_engine = make_cl_engine(old);
        w = {.before = &old, .radiosity = p, .engine = old_engine.get(),
             .match = match_patches(mesh, old, 1e-6 * mesh.bound_radius), .error = p_error};
        so.warm = &w;
        so.shots_per_bundle = 0;
      }
      auto engine = make_cl_engine(mesh);
      std::unique_ptr<ShotEngine> shots;
      if (so.shots_per_bundle > 0) shots = make_cl_shot_engine(mesh);
      Solver s(mesh, *engine, so, shots.get());
      const uint64_t bundles = run_to(s, target, cap);
      const double t = seconds_since(t0);
      times[warm].push_back(t);
      const std::vector<glm::vec3> x = s.estimate();
      std::printf("%s,%d,%llu,%.3f,%.5f,%.5f,%.5f\n", warm ? "warm" : "cold", rep, static_cast<unsigned long long>(bundles), t,
                  s.error_estimate(), measured(x), mean_ratio(after_alone, x, ref));
      std::fflush(stdout);
    }
  }
  std::printf("# median seconds to %.3g: cold %.3f, warm %.3f, ratio %.2f\n", target, median(times[0]), median(times[1]),
              median(times[0]) / median(times[1]));
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "sirad_bench_warm: %s\n", e.what());
  return 1;
}
