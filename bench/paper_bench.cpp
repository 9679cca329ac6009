// sirad paper bench: the real-run experiments of bench/paper on the virtual-time
// cluster (cluster/emulate.h), CSV on stdout; bench/paper/*.sh run it and plot.
//
//   sirad_bench_paper fig6   --scene cornell --patches 2000 --seeds 5   (figure 6: error against I
//                            for 50/100/200 bundles on P = 1, 2, 4, 8, and time against P)
//   sirad_bench_paper hetero --profile deploy/profiles/hetero-16.yaml --target 0.02
//                            (time to the target error: sync/async x star/ring x I)
//
// Errors are measured against a reference solution (solver/reference.h; computed once and kept
// in --reference, default SCENE-PATCHES.ref.csv): relative RMS per non-emitting patch,
// area-weighted, the reference's own variance subtracted (solver/metrics.h).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "cli/run_flags.h"
#include "cluster/emulate.h"
#include "cluster/profile.h"
#include "engine/bundle_cl.h"
#include "model/model.h"
#include "model/model_fit.h"
#include "scene/scene.h"
#include "solver/metrics.h"
#include "solver/reference.h"
#include "util/error.h"

namespace sirad {
namespace {

struct Common {
  std::string scene = "cornell", reference;
  int64_t patches = 2000;
  int ref_rays = 4096;
  std::string device;
};

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');) out.push_back(item);
  return out;
}

struct Setup {
  Scene scene;
  PatchMesh mesh;
  ReferenceSolution ref;
  std::unique_ptr<BundleEngine> engine;
  std::unique_ptr<ShotEngine> shots;
};

Setup setup(const Common& c) {
  Setup s;
  s.scene = load_scene(c.scene, {});
  MeshOptions mo;
  mo.target_patches = static_cast<std::size_t>(c.patches);
  s.mesh = mesh_scene(s.scene, mo);
  std::string path = c.reference.empty()
                         ? fmt::format("{}-{}.ref.csv", std::filesystem::path(c.scene).stem().string(), c.patches)
                         : c.reference;
  if (std::filesystem::exists(path)) {
    s.ref = read_reference(path, s.mesh);
  } else {
    ReferenceOptions ro;
    ro.rays_per_patch = c.ref_rays;
    ro.light_samples = 512;
    std::fprintf(stderr, "computing the reference (%zu patches, %d rays per patch) into %s...\n", s.mesh.size(), ro.rays_per_patch,
                 path.c_str());
    s.ref = solve_reference(s.mesh, ro);
    write_reference(path, s.mesh, s.ref, ro);
  }
  std::fprintf(stderr, "reference: mean relative SE %.4f\n", mean_relative_se(s.mesh, s.ref));
  s.engine = make_cl_engine(s.mesh, {.device = c.device});
  s.shots = make_cl_shot_engine(s.mesh, c.device);
  return s;
}

double error_of(const Setup& s, const std::vector<glm::vec3>& radiosity) {
  return relative_rms_vs_reference(s.mesh, radiosity, s.ref.radiosity, s.ref.radiosity_se).corrected;
}

// Figure 6: P processors each run total / P bundles of the paper's algorithm (average rule,
// plain estimator: no first shot, no control variate, random directions) or of sirad's defaults
// (--estimator sirad), exchanging every I; error against I, and virtual time against P with
// the measured bundle time. The model's prediction from the scene's fitted a and sigma_1 / C:
// section 2's error (bias + 3 sd) and its sd part alone.
int fig6(const Common& c, int seeds, const std::string& totals_s, const std::string& procs_s, const std::string& periods_s,
         const std::string& estimator, const std::string& profile) {
  Setup s = setup(c);
  model::FitOptions fo;
  model::SceneFit fit = model::fit_scene(s.mesh, *s.engine, fo);
  model::Scene ms{std::clamp(fit.contraction, 0.0, 0.99), fit.sigma_ratio};
  std::fprintf(stderr, "fit: a = %.4f +- %.4f, sigma_1 / C = %.3f, T_i = %.6f s\n", fit.contraction, fit.contraction_se,
               fit.sigma_ratio, fit.t_iteration);
  cluster::RunConfig base;
  base.scene = s.scene;
  base.mesh_options.target_patches = static_cast<std::size_t>(c.patches);
  if (estimator == "paper") {
    base.rule = UpdateRule::average;
    base.directions = Directions::random;
    base.control_variate = false;
    base.shots_per_bundle = 0;
  } else {
    base.rule = UpdateRule::chain;
    base.directions = Directions::stratified;
    base.shots_per_bundle = cli::settings_from({}, {}).shots_per_bundle;
  }
  base.mode = cluster::Mode::sync;
  if (!profile.empty()) base.profile = emulation::load_profile(profile);
  double bundle_s = cluster::measure_bundle_seconds(s.mesh, *s.engine, s.shots.get(), cluster::solver_options(base, s.mesh, 0), 15);
  std::fprintf(stderr, "bundle time %.6f s (median of 15)\n", bundle_s);
  std::printf("estimator,total,processors,period,seed,error,virtual_s,bundle_s,exchanges,model_error,model_sd,contraction,sigma_ratio\n");
  for (const std::string& t : split(totals_s))
    for (const std::string& p : split(procs_s))
      for (const std::string& i : split(periods_s)) {
        uint64_t total = std::stoull(t);
        uint32_t P = static_cast<uint32_t>(std::stoul(p));
        uint32_t I = cluster::parse_exchange_every(i);
        if (P > total) continue;
        uint64_t per_node = total / P;
        if (I != 0 && I > per_node) continue;  // no exchange would happen: the same as "end"
        auto ls = model::log_sample_numbers(per_node, {P, I, 1.0});
        double merr = model::relative_error(ls, ms);
        double msd = (merr - std::pow(ms.contraction, static_cast<double>(per_node) + 1)) / 3;
        for (int seed = 1; seed <= seeds; ++seed) {
          cluster::EmulateConfig ec;
          ec.run = base;
          ec.run.bundles = per_node * P;
          ec.run.seed = static_cast<uint64_t>(seed);
          ec.run.exchange_every = I;
          ec.nodes = P;
          ec.run.min_nodes = P;  // the paper's processors start together
          ec.bundle_s = bundle_s;
          cluster::EmulateResult r = cluster::emulate(ec, s.mesh, *s.engine, s.shots.get());
          std::printf("%s,%llu,%u,%s,%d,%.6f,%.6f,%.6g,%u,%.6f,%.6f,%.4f,%.4f\n", estimator.c_str(),
                      static_cast<unsigned long long>(total), P, i.c_str(), seed, error_of(s, r.run.radiosity), r.wall_s,
                      bundle_s, r.run.exchanges, merr, msd, ms.contraction, ms.sigma_ratio);
          std::fflush(stdout);
        }
      }
  return 0;
}

// The heterogeneous farm: time (virtual) until the run's own error estimate reaches the target,
// for sync / async x star / ring x each period, sirad's default estimator; the measured error
// at that point beside it, and the nodes' utilisation.
int hetero(const Common& c, const std::string& profile_path, double target, int seeds, const std::string& periods_s,
           uint64_t cap, const std::string& topologies, const std::string& balances) {
  Setup s = setup(c);
  emulation::Profile profile = emulation::load_profile(profile_path);
  cluster::RunConfig base;
  base.scene = s.scene;
  base.mesh_options.target_patches = static_cast<std::size_t>(c.patches);
  base.directions = Directions::stratified;
  base.shots_per_bundle = cli::settings_from({}, {}).shots_per_bundle;
  base.target_error = target;
  base.bundles = cap;
  base.profile = profile;
  const uint32_t P = static_cast<uint32_t>(profile.nodes.size());
  double bundle_s = cluster::measure_bundle_seconds(s.mesh, *s.engine, s.shots.get(), cluster::solver_options(base, s.mesh, 0), 15);
  std::fprintf(stderr, "%u nodes, bundle time %.6f s at speed %g (median of 15)\n", P, bundle_s, profile.max_speed());
  std::printf("mode,topology,balance,period,chosen_period,fraction,seed,virtual_s,bundles,error_estimate,error,exchanges,"
              "utilisation_mean,utilisation_min,idle_s_total,ended_by\n");
  for (const char* mode : {"sync", "async"})
    for (const std::string& topo : split(topologies))
     for (const std::string& balance : split(balances))
      for (const std::string& i : split(periods_s))
        for (int seed = 1; seed <= seeds; ++seed) {
          cluster::EmulateConfig ec;
          ec.run = base;
          ec.run.balance = balance == "on";
          ec.run.mode = cluster::parse_mode(mode);
          ec.run.topology = cluster::parse_topology(topo);
          ec.run.exchange_every = cluster::parse_exchange_every(i);
          ec.run.seed = static_cast<uint64_t>(seed);
          ec.nodes = P;
          ec.run.min_nodes = P;  // as bench/paper/REPORT.md measured it: every node before the first grant
          ec.bundle_s = bundle_s;
          cluster::EmulateResult r = cluster::emulate(ec, s.mesh, *s.engine, s.shots.get());
          double use = 0, use_min = 1, idle = 0;
          for (const auto& n : r.nodes) {
            use += n.utilisation / static_cast<double>(r.nodes.size());
            use_min = std::min(use_min, n.utilisation);
            idle += n.idle_s;
          }
          std::string ended = r.run.ended_by.substr(0, r.run.ended_by.find(' '));
          std::printf("%s,%s,%s,%s,%s,%g,%d,%.6f,%llu,%.6f,%.6f,%u,%.4f,%.4f,%.4f,%s\n", mode, topo.c_str(), balance.c_str(), i.c_str(),
                      cluster::exchange_every_name(r.run.exchange_every).c_str(), r.run.fraction, seed, r.wall_s,
                      static_cast<unsigned long long>(r.run.bundles), r.error_estimate, error_of(s, r.run.radiosity),
                      r.run.exchanges, use, use_min, idle, ended.c_str());
          std::fflush(stdout);
        }
  return 0;
}

int run(int argc, char** argv) {
  CLI::App app{"sirad paper bench: figure 6 and the heterogeneous farm on the virtual-time cluster (CSV)"};
  app.require_subcommand(1);
  Common c;
  auto common = [&](CLI::App* cmd) {
    cmd->add_option("--scene", c.scene, "Scene")->capture_default_str();
    cmd->add_option("--patches", c.patches, "Target patches")->check(CLI::Range(int64_t{1}, int64_t{1} << 24))->capture_default_str();
    cmd->add_option("--reference", c.reference, "Reference solution file (computed and written if missing)");
    cmd->add_option("--ref-rays", c.ref_rays, "Reference rays per patch when computing it")->check(CLI::Range(64, 1 << 20));
    cmd->add_option("--device", c.device, "OpenCL device");
  };
  int seeds = 5;
  std::string totals = "50,100,200", procs = "1,2,4,8", periods = "1,2,3,5,10,25,end", estimator = "paper", f6_profile;
  auto* f6 = app.add_subcommand("fig6", "Figure 6: error against I, time against P");
  common(f6);
  f6->add_option("--seeds", seeds, "Seeds per setting")->check(CLI::Range(1, 1000))->capture_default_str();
  f6->add_option("--totals", totals, "Total bundles")->capture_default_str();
  f6->add_option("--processors", procs, "Processor counts")->capture_default_str();
  f6->add_option("--periods", periods, "Exchange periods I (or end)")->capture_default_str();
  f6->add_option("--estimator", estimator, "paper (average rule, plain) or sirad (the defaults)")
      ->check(CLI::IsMember({"paper", "sirad"}))->capture_default_str();
  f6->add_option("--profile", f6_profile, "Emulation profile for the links and speeds (default: unshaped, all alike)");
  std::string profile = "deploy/profiles/hetero-16.yaml", hetero_periods = "8,32,auto";
  double target = 0.02;
  int hetero_seeds = 2;
  uint64_t cap = 20000;
  std::string topologies = "star,ring", balances = "on,off";
  auto* h = app.add_subcommand("hetero", "Time to the target error on a heterogeneous farm");
  common(h);
  h->add_option("--profile", profile, "Emulation profile")->capture_default_str();
  h->add_option("--target", target, "Target error (the run's own estimate)")->check(CLI::Range(1e-4, 0.5))->capture_default_str();
  h->add_option("--seeds", hetero_seeds, "Seeds per setting")->check(CLI::Range(1, 100))->capture_default_str();
  h->add_option("--periods", hetero_periods, "Exchange periods I (or end, auto)")->capture_default_str();
  h->add_option("--cap", cap, "Bundle budget (the run ends at the target before it)")->capture_default_str();
  h->add_option("--topologies", topologies, "Topologies to run")->capture_default_str();
  h->add_option("--balance", balances, "Balanced grants: on, off or both")->capture_default_str();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (f6->parsed()) return fig6(c, seeds, totals, procs, periods, estimator, f6_profile);
  return hetero(c, profile, target, hetero_seeds, hetero_periods, cap, topologies, balances);
}

}  // namespace
}  // namespace sirad

int main(int argc, char** argv) {
  try {
    return sirad::run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad_bench_paper: error: %s\n", e.what());
    return 1;
  }
}
