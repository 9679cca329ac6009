// sirad bench: accuracy per second. Runs the solver in one or more configurations
// against a reference solution (`sirad reference`, solver/reference.h) and prints, as CSV, the
// relative RMS error per non-emitting patch (area-weighted, the reference's own variance
// subtracted: solver/metrics.h relative_rms_vs_reference) at checkpoints of growing bundle counts,
// with the solver's wall time up to there (error evaluation not counted) and the process's CPU
// time over the same steps (all threads). The summary lines
// give the time to 2 % and to 1 % of each configuration (the first checkpoint at or below).
//
//   sirad_bench_accuracy --scene cornell --patches 20000 --reference cornell-20000.ref.csv
//       --config naive --config shot:1 --config shot:0.5:128 --max-seconds 60
//
// A configuration is `naive` (no first shot), `shot:X[:H]` (X shots per bundle, hemicube side H,
// 0 or absent: auto) or `direct[:H]` (the first shot alone against the reference's direct part
// D: what its error costs in time, apart from the bundles), followed by options
// `/stratified` or `/random` (directions and shot points), `/cv` or `/nocv` (the transport's
// control variate, on by default) and `/grid=R`. The reference file is computed (and written)
// when missing.
#include <chrono>
#include <ctime>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "engine/bundle_cl.h"
#include "engine/shot.h"
#include "scene/scene.h"
#include "solver/metrics.h"
#include "solver/reference.h"
#include "solver/solver.h"
#include "util/error.h"

using namespace sirad;

namespace {

// CPU time of the whole process (every PoCL thread included).
double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

struct Config {
  std::string name;
  double shots_per_bundle = 0.0;
  int resolution = 0;
  bool direct_only = false;
  Directions directions = Directions::random;
  bool control_variate = true;
  int grid = 0;  // 0: --grid
};

Config parse_one(const std::string& text);

// `CONFIG[/OPTION...]`: the configuration with options: random | stratified (bundle
// directions), cv | nocv (the transport's control variate, on by default).
Config parse_config(const std::string& text) {
  std::size_t slash = text.find('/');
  Config c = parse_one(text.substr(0, slash));
  while (slash != std::string::npos) {
    std::size_t next = text.find('/', slash + 1);
    std::string option = text.substr(slash + 1, next == std::string::npos ? std::string::npos : next - slash - 1);
    if (option == "cv" || option == "nocv") {
      c.control_variate = option == "cv";
    } else if (option.rfind("grid=", 0) == 0) {
      try {
        c.grid = std::stoi(option.substr(5));
      } catch (const std::exception&) {
        fail("--config {}: expected grid=N", text);
      }
    } else {
      c.directions = parse_directions(option);
    }
    slash = next;
  }
  c.name = text;
  return c;
}

Config parse_one(const std::string& text) {
  if (text == "naive") return {text, 0.0, 0};
  if (text == "direct" || text.rfind("direct:", 0) == 0) {
    Config c{text, 0.0, 0, true};
    try {
      if (text.size() > 7) c.resolution = std::stoi(text.substr(7));
    } catch (const std::exception&) {
      fail("--config {}: expected direct[:H]", text);
    }
    check_first_shot(0.0, c.resolution);
    return c;
  }
  if (text.rfind("shot:", 0) != 0) fail("--config {}: expected naive or shot:X[:H]", text);
  Config c{text, 0.0, 0};
  std::string rest = text.substr(5);
  std::size_t colon = rest.find(':');
  try {
    c.shots_per_bundle = std::stod(rest.substr(0, colon));
    if (colon != std::string::npos) c.resolution = std::stoi(rest.substr(colon + 1));
  } catch (const std::exception&) {
    fail("--config {}: expected naive or shot:X[:H]", text);
  }
  check_first_shot(c.shots_per_bundle, c.resolution);
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"sirad_bench_accuracy: error against a reference over time (CSV)"};
  std::string scene_spec = "cornell", reference_path;
  int64_t patches = 20000;
  std::vector<std::string> configs;
  double max_seconds = 60.0;
  uint64_t seed = 1;
  int grid = 0;
  app.add_option("--scene", scene_spec)->capture_default_str();
  app.add_option("--patches", patches)->capture_default_str();
  app.add_option("--reference", reference_path, "NAME.ref.csv (computed with 8192 rays per patch if missing)");
  app.add_option("--config", configs, "naive or shot:X[:H] (repeatable)");
  app.add_option("--max-seconds", max_seconds, "Solver time per configuration")->capture_default_str();
  app.add_option("--seed", seed)->capture_default_str();
  app.add_option("--grid", grid, "Lines per side (0: auto)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    if (configs.empty()) configs = {"naive", "shot:1"};
    std::vector<Config> parsed;
    for (const auto& c : configs) parsed.push_back(parse_config(c));
    PatchMesh mesh = mesh_scene(load_scene(scene_spec), {.target_patches = static_cast<std::size_t>(patches)});
    if (reference_path.empty()) reference_path = fmt::format("{}-{}.ref.csv", std::filesystem::path(scene_spec).stem().string(), patches);
    ReferenceSolution ref;
    if (std::filesystem::exists(reference_path)) {
      ref = read_reference(reference_path, mesh);
    } else {
      ReferenceOptions ro;
      ro.rays_per_patch = 8192;
      std::fprintf(stderr, "computing the reference (%zu patches, %d rays per patch)...\n", mesh.size(), ro.rays_per_patch);
      ref = solve_reference(mesh, ro);
      write_reference(reference_path, mesh, ref, ro);
    }
    std::fprintf(stderr, "reference: mean relative SE %.4f\n", mean_relative_se(mesh, ref));

    auto engine = make_cl_engine(mesh);
    auto shots = make_cl_shot_engine(mesh);
    std::printf("config,patches,seed,bundles,shots,seconds,error_raw,error,cpu_seconds\n");
    std::vector<std::string> summary;
    for (const Config& c : parsed) {
      if (c.direct_only) {
        // Shots only: D estimated from shots 0..k-1 against the reference's D.
        const int H = c.resolution ? c.resolution : auto_shot_resolution(mesh);
        std::vector<glm::dvec3> direct(mesh.size(), glm::dvec3(0.0));
        EmitterTable table = emitter_table(mesh);
        double s = 0.0, to2 = -1, to1 = -1;
        uint64_t next = 4;
        for (uint64_t k = 0; s < max_seconds; ++k) {
          auto t0 = std::chrono::steady_clock::now();
          ShotSums one = run_shots(mesh, table, *shots, H, seed, k, 1, Stream::shots, c.directions == Directions::stratified);
          for (std::size_t j = 0; j < direct.size(); ++j) direct[j] += one.direct[j];
          s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          if (k + 1 < next) continue;
          next = std::max(next + 1, static_cast<uint64_t>(next * 1.15));
          std::vector<glm::vec3> d(mesh.size());
          for (std::size_t j = 0; j < d.size(); ++j) d[j] = glm::vec3(direct[j] / static_cast<double>(k + 1));
          ReferenceError e = relative_rms_vs_reference(mesh, d, ref.direct, ref.direct_se);
          std::printf("%s,%zu,%llu,0,%llu,%.3f,%.5f,%.5f,\n", c.name.c_str(), mesh.size(), static_cast<unsigned long long>(seed),
                      static_cast<unsigned long long>(k + 1), s, e.raw, e.corrected);
          std::fflush(stdout);
          if (to2 < 0 && e.corrected <= 0.02) to2 = s;
          if (to1 < 0 && e.corrected <= 0.01) to1 = s;
          if (to1 >= 0) break;
        }
        summary.push_back(fmt::format("# {} (D alone): {} patches, H {}, time to 2 %: {}, to 1 %: {}", c.name, mesh.size(), H,
                                      to2 < 0 ? "not reached" : fmt::format("{:.2f} s", to2),
                                      to1 < 0 ? "not reached" : fmt::format("{:.2f} s", to1)));
        continue;
      }
    }
    // The solver configurations run interleaved, in slices of about half a second each, so a
    // change in the machine's speed (a shared VM's varies by 1.5x over minutes) falls on all
    // of them alike; each one's time is its own solver time only.
    struct Run {
      const Config* config;
      std::unique_ptr<Solver> solver;
      double seconds = 0.0, cpu = 0.0, to2 = -1.0, to1 = -1.0;
      uint64_t next = 4;
      bool done = false;
    };
    std::vector<Run> runs;
    for (const Config& c : parsed) {
      if (c.direct_only) continue;
      SolverOptions so;
      so.seed = seed;
      so.grid = c.grid ? c.grid : grid;
      so.shots_per_bundle = c.shots_per_bundle;
      so.shot_resolution = c.resolution;
      so.directions = c.directions;
      so.control_variate = c.control_variate;
      Run run{&c};
      auto t0 = std::chrono::steady_clock::now();
      double c0 = process_cpu_seconds();
      run.solver = std::make_unique<Solver>(mesh, *engine, so, shots.get());  // set-up and burn-in count
      run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      run.cpu = process_cpu_seconds() - c0;
      runs.push_back(std::move(run));
    }
    for (bool any = true; any;) {
      any = false;
      for (Run& run : runs) {
        if (run.done) continue;
        any = true;
        Solver& solver = *run.solver;
        for (double slice = 0.0; slice < 0.5 && run.seconds < max_seconds;) {
          auto t0 = std::chrono::steady_clock::now();
          double c0 = process_cpu_seconds();
          solver.step(solver.bundles());
          double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          run.cpu += process_cpu_seconds() - c0;
          slice += dt;
          run.seconds += dt;
          if (solver.bundles() < run.next) continue;
          run.next = std::max(run.next + 1, static_cast<uint64_t>(run.next * 1.15));
          ReferenceError e = relative_rms_vs_reference(mesh, solver.estimate(), ref.radiosity, ref.radiosity_se);
          std::printf("%s,%zu,%llu,%llu,%llu,%.3f,%.5f,%.5f,%.3f\n", run.config->name.c_str(), mesh.size(),
                      static_cast<unsigned long long>(seed), static_cast<unsigned long long>(solver.bundles()),
                      static_cast<unsigned long long>(solver.shots_rendered()), run.seconds, e.raw, e.corrected, run.cpu);
          std::fflush(stdout);
          if (run.to2 < 0 && e.corrected <= 0.02) run.to2 = run.seconds;
          if (run.to1 < 0 && e.corrected <= 0.01) run.to1 = run.seconds;
          if (run.to1 >= 0) break;
        }
        run.done = run.to1 >= 0 || run.seconds >= max_seconds;
      }
    }
    for (const Run& run : runs)
      summary.push_back(fmt::format("# {}: {} patches, grid {}, H {}, time to 2 %: {}, to 1 %: {}", run.config->name, mesh.size(),
                                    run.solver->grid(), run.solver->shot_resolution(),
                                    run.to2 < 0 ? "not reached" : fmt::format("{:.2f} s", run.to2),
                                    run.to1 < 0 ? "not reached" : fmt::format("{:.2f} s", run.to1)));
    for (const auto& s : summary) std::printf("%s\n", s.c_str());
  } catch (const Error& e) {
    std::fprintf(stderr, "sirad_bench_accuracy: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
