// sirad: `sirad render` (one node, or an embedded cluster) and `sirad emulate` (the virtual-time
// cluster), and `sirad profile` (see commands.h).
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>

#include <fmt/format.h>

#include "cli/commands.h"
#include "cli/embedded.h"
#include "cli/scene_outputs.h"
#include "cluster/emulate.h"
#include "cluster/live_view.h"
#include "cluster/policy.h"
#include "cluster/profile.h"
#include "cluster/single_node.h"
#include "cluster/status.h"
#include "engine/bundle_cl.h"
#include "engine/shot.h"
#include "io/read_solution.h"
#include "io/results.h"
#include "solver/solver.h"
#include "solver/warm_start.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace sirad::cli {
namespace {

// SIGINT / SIGTERM during `sirad render`: the first ends the run with the bundles done so far
// (the estimate is unbiased at any count) and writes it; a second one ends the process at once
// (outputs are written atomically: nothing half-written is left).
std::atomic<int> g_signal{0};
std::atomic<bool> g_interrupted{false};
void on_interrupt(int sig) {
  if (g_signal.exchange(sig) != 0) {
    std::signal(sig, SIG_DFL);
    std::raise(sig);
    return;
  }
  g_interrupted = true;
}
void install_interrupt() {
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);
}
std::string interrupted_by() { return g_signal.load() == SIGINT ? "interrupted (SIGINT)" : "interrupted (SIGTERM)"; }

// Refuses the flags of `flags` that were given, with `why` (a flag that has no effect in a mode
// is an error, never ignored).
void refuse_given(const RenderArgs& a, const std::vector<std::string>& flags, const std::string& why) {
  for (const std::string& f : flags)
    if (a.given.count(f)) fail("{} {}", f, why);
}

// A progress bar on a terminal, a plain line every 10% otherwise.
class Progress {
 public:
  Progress(int64_t total, bool quiet) : total_(total), quiet_(quiet), tty_(::isatty(STDERR_FILENO)) {}
  void update(int64_t done, double seconds) {
    if (quiet_) return;
    double rate = seconds > 0 ? done / seconds : 0.0;
    if (tty_) {
      auto now = std::chrono::steady_clock::now();
      if (done != total_ && now - last_ < std::chrono::milliseconds(100)) return;
      last_ = now;
      int width = 30, filled = static_cast<int>(width * done / std::max<int64_t>(total_, 1));
      double eta = rate > 0 ? (total_ - done) / rate : 0.0;
      std::fprintf(stderr, "\r[%s%s] %lld/%lld bundles  %.1f bundles/s  ETA %.0fs ",
                   std::string(filled, '#').c_str(), std::string(width - filled, '.').c_str(),
                   static_cast<long long>(done), static_cast<long long>(total_), rate, eta);
      if (done == total_) std::fprintf(stderr, "\n");
    } else if (done * 10 / std::max<int64_t>(total_, 1) > reported_ * 10 / std::max<int64_t>(total_, 1) || done == total_) {
      reported_ = done;
      std::fprintf(stderr, "sirad: %lld/%lld bundles, %.1f bundles/s\n", static_cast<long long>(done),
                   static_cast<long long>(total_), rate);
    }
  }

 private:
  int64_t total_;
  bool quiet_, tty_;
  int64_t reported_ = 0;
  std::chrono::steady_clock::time_point last_{};
};

// What a run that stopped at its bundle cap short of its --target-error says: on stdout, and as
// sirad.ended_by in the EXR ("" when it met the target or had none).
std::string short_of_target(const cluster::RunSettings& s, const std::string& ended_by, double estimate) {
  if (!(s.target_error > 0) || ended_by != "budget") return "";
  return fmt::format("bundle cap {} reached short of the target error {} (estimate {})", s.bundles, s.target_error,
                     estimate >= 0 ? fmt::format("{:.4f}", estimate) : std::string("n/a"));
}

// The last line of a render that did not simply run its budget, and the exit status: an
// interrupted run wrote the result of the bundles done and exits 128 + the signal.
int finish_line(const std::string& ended_by, const std::string& short_of, int64_t done) {
  if (!short_of.empty()) std::printf("ended short of the target: %s\n", short_of.c_str());
  else if (ended_by != "budget") std::printf("ended early: %s\n", ended_by.c_str());
  if (g_interrupted) {
    std::printf("interrupted after %lld bundles: the outputs hold the result of those (unbiased, with less "
                "precision); a second signal ends sirad at once\n", static_cast<long long>(done));
    return 128 + g_signal.load();
  }
  return 0;
}

// The embedded default: the coordinator on this thread, N nodes on their own threads, all over
// ZeroMQ inproc with the same code as a cluster (cli/embedded.h).
int render_embedded(const RenderArgs& a, const cluster::RunSettings& settings, const Meshed& m, const std::string& out,
                    std::optional<emulation::Profile> profile) {
  cluster::RunConfig rc;
  static_cast<cluster::RunSettings&>(rc) = settings;
  rc.scene = m.scene;
  rc.min_nodes = static_cast<uint32_t>(a.nodes);
  rc.profile = std::move(profile);
  rc.close = &g_interrupted;
  cluster::StatusReporter reporter(a.quiet, a.status_json);
  rc.status_every_s = 0.25;
  rc.status = std::ref(reporter);
  rc.final_gather = final_gather_of(cli::result_options(a.output));  // the image's tiles rendered by the node threads
  std::string short_of;
  embedded::Options eo{.nodes = a.nodes, .device = a.device, .transfer = a.transfer};
  eo.on_done = [&](const cluster::RunResult& result) {
    reporter.finish();
    Attributes attrs = cluster::run_attributes(rc, cluster::outcome_of(result), m.mesh, a.scene, true);
    short_of = short_of_target(rc, result.ended_by, result.error_estimate);
    if (!short_of.empty())
      for (auto& [key, value] : attrs)
        if (key == "sirad.ended_by") value = short_of;
    write_outputs(a.output, out, m, result.radiosity, attrs, result.image ? &*result.image : nullptr, result.image_error);
  };
  embedded::Outcome o = embedded::run(rc, m.mesh, eo);
  const cluster::RunResult& result = o.result;
  std::fputs(cluster::cluster_summary(result, m.mesh.size(), o.coordinate_s).c_str(), stdout);
  return finish_line(result.ended_by, short_of, static_cast<int64_t>(result.bundles));
}

// --warm-start's refusals that need no file read: it runs on one node, under the chain rule,
// without a first shot, from a PLY (a glb holds corner values and sides pulled apart, not the
// solution on its patches: as a control variate it would bias the answer).
void check_warm_start(const RenderArgs& a, const cluster::RunSettings& s) {
  const std::string& f = a.warm_start;
  if (a.nodes > 0) fail("--warm-start {}: a warm start runs on one node (no --nodes)", f);
  if (s.rule != UpdateRule::chain) fail("--warm-start {}: a warm start needs --rule chain", f);
  if (s.shots_per_bundle > 0) fail("--warm-start {}: a warm start takes no first shot (the previous solution holds the direct light): drop --shots-per-bundle", f);
  if (std::filesystem::path(f).extension() != ".ply")
    fail("--warm-start {}: give the previous run's PLY (its glb holds the solution at corners, not on its patches)", f);
}

// A warm start's previous solution, its patches framed as the new mesh's, their engine and the
// match (solver/warm_start.h).
struct Warm {
  Solution before;
  std::unique_ptr<BundleEngine> engine;
  WarmStart start;

  Warm(const RenderArgs& a, const cluster::RunSettings& s, PatchMesh& mesh) : before(read_solution(a.warm_start)) {
    if (!before.error_estimate)
      fail("--warm-start {}: the file does not say its run's error estimate (comment sirad error estimate): run it again "
           "with this sirad", a.warm_start);
    if (s.target_error > 0 && *before.error_estimate >= s.target_error)
      fail("--warm-start {}: its own error {:.4f} is not below --target-error {}: a run from it cannot reach the target; "
           "run without --warm-start", a.warm_start, *before.error_estimate, s.target_error);
    share_bound(mesh, before.mesh);
    engine = make_cl_engine(before.mesh, {.device = a.device, .path = a.transfer});
    start.before = &before.mesh;
    start.radiosity = before.radiosity;
    start.engine = engine.get();
    start.match = match_patches(mesh, before.mesh, 1e-6 * static_cast<double>(mesh.bound_radius));
    start.error = *before.error_estimate;
    const auto matched = std::count_if(start.match.begin(), start.match.end(), [](int64_t i) { return i >= 0; });
    if (!a.quiet)
      std::fprintf(stderr, "sirad: warm start from %s: %lld of %zu patches where one of its %zu was (its error %.4f)\n",
                   a.warm_start.c_str(), static_cast<long long>(matched), mesh.size(), before.mesh.size(), start.error);
  }
};

}  // namespace

int render(RenderArgs a) {
  // Check everything cheap before any work: flags, output place, scene, device.
  if (!a.profile.empty() && a.nodes == 0) fail("--profile {}: emulation needs a cluster (--nodes N)", a.profile);
  if (a.nodes == 0) {
    std::vector<std::string> cluster_only = cli::cluster_flag_names();
    cluster_only.push_back("--status-json");
    refuse_given(a, cluster_only, "has no effect on one node: it is a cluster setting (--nodes N)");
  }
  cluster::RunSettings settings = cli::settings_from(a.run, a.given);
  // A warm start's previous solution holds the direct light: no first shot unless one is asked
  // for (refused below).
  if (!a.warm_start.empty() && !a.given.count("--shots-per-bundle")) settings.shots_per_bundle = 0.0;
  if (a.nodes > 0) {
    if (std::string why = cluster::target_error_problem(settings); !why.empty()) fail("{}", why);
  }
  std::optional<emulation::Profile> profile;
  if (!a.profile.empty()) profile = emulation::load_profile(a.profile);
  if (settings.target_error > 0 && a.nodes == 0 && settings.rule != UpdateRule::chain)
    fail("--target-error on one node needs --rule chain (its batch means assume the chain's estimates)");
  if (!a.warm_start.empty()) check_warm_start(a, settings);
  std::string out = output_name(a.output.out, a.scene, a.output.lightmap.on ? kLightmapEndings : std::vector<std::string>{});
  Meshed m = load_meshed(a.scene, settings.mesh_options,
                         a.output.import(), a.output.camera);
  cli::settle_image_size(a.output, m.scene);
  if (a.output.lightmap.on) lightmap_atlas(a.output.lightmap, m.scene);  // a texel size the atlas cannot take: refused before the solve
  std::optional<Warm> warm;
  if (!a.warm_start.empty()) warm.emplace(a, settings, m.mesh);  // before the engine: the meshes share one bounding sphere
  const PatchMesh& mesh = m.mesh;
  install_interrupt();

  if (a.nodes > 0) {
    // Two or more nodes in this process on PoCL's CPU device would each get a pool of threads
    // for every kernel: oversubscribed, and woken once per launch. Unless the user chose PoCL's
    // devices or a device, each node gets PoCL's single-threaded CPU device instead (one chain
    // per core, like one thread per MPI rank; measured in bench/RESULTS.md). Must precede any
    // OpenCL call.
    if (a.nodes >= 2 && a.device.empty() && std::getenv("SIRAD_DEVICE") == nullptr && std::getenv("POCL_DEVICES") == nullptr)
      setenv("POCL_DEVICES", "basic", 0);
    return render_embedded(a, settings, m, out, std::move(profile));
  }
  auto engine = make_cl_engine(mesh, {.device = a.device, .path = a.transfer});
  SolverOptions so = cluster::solver_options(settings, mesh, 0);
  so.track_error = settings.target_error > 0 || mesh.size() <= kTrackErrorMaxPatches;
  if (warm) so.warm = &warm->start;
  std::unique_ptr<ShotEngine> shots;
  if (so.shots_per_bundle > 0) shots = make_cl_shot_engine(mesh, a.device);
  const int64_t bundles = static_cast<int64_t>(settings.bundles);
  if (!a.quiet)
    std::fprintf(stderr, "sirad: %s: %zu patches, grid %d, %lld bundles (%s rule, %s directions), %g shots per bundle, on %s\n",
                 a.scene.c_str(), mesh.size(), so.grid, static_cast<long long>(bundles), to_string(so.rule),
                 to_string(so.directions), so.shots_per_bundle, engine->description().c_str());

  auto start = std::chrono::steady_clock::now();
  Solver solver(mesh, *engine, so, shots.get());
  Progress progress(bundles, a.quiet);
  const double setup_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const cluster::SingleRun run = cluster::run_single(solver, settings, &g_interrupted, interrupted_by,
                                                     [&](uint64_t done, double t) { progress.update(static_cast<int64_t>(done), t); },
                                                     setup_s);
  const std::string& ended_by = run.ended_by;
  const auto done = static_cast<int64_t>(run.bundles);
  const double seconds = run.seconds;
  double error = solver.error_estimate();

  const std::string short_of = short_of_target(settings, ended_by, error);
  Attributes attrs = cluster::run_attributes(
      settings,
      {static_cast<uint64_t>(done), solver.grid(), 1, 0, 1.0, short_of.empty() ? ended_by : short_of, seconds, solver.crossings()},
      mesh, a.scene, false);
  attrs.emplace_back("sirad.burn_in", static_cast<int64_t>(solver.burn_in()));
  attrs.emplace_back("sirad.shot_resolution", static_cast<int64_t>(solver.shot_resolution()));
  attrs.emplace_back("sirad.shots", static_cast<int64_t>(solver.shots_rendered()));
  if (error >= 0) attrs.emplace_back("sirad.error_estimate", error);
  if (settings.target_error > 0) attrs.emplace_back("sirad.target_error", settings.target_error);
  attrs.emplace_back("sirad.device", engine->description());
  write_outputs(a.output, out, m, solver.estimate(), attrs);
  std::printf("%s\n", cluster::summary_line(mesh.size(), static_cast<uint64_t>(done), solver.grid(), 0, seconds, solver.crossings(),
                                            fmt::format(", error estimate {}", error >= 0 ? fmt::format("{:.4f}", error) : "n/a"))
                          .c_str());
  return finish_line(ended_by, short_of, done);
}

int emulate(EmulateArgs& e) {
  RenderArgs& a = e.run;
  std::optional<emulation::Profile> profile;
  if (!a.profile.empty()) profile = emulation::load_profile(a.profile);
  if (!a.given.count("--nodes")) {
    if (!profile || profile->nodes.empty()) fail("emulate: give --nodes N (or a --profile with node entries)");
    a.nodes = static_cast<int>(profile->nodes.size());
  }
  const cluster::RunSettings settings = cli::settings_from(a.run, a.given);
  if (std::string why = cluster::target_error_problem(settings); !why.empty()) fail("{}", why);
  std::string out = output_name(a.output.out, a.scene, a.output.lightmap.on ? kLightmapEndings : std::vector<std::string>{});
  Meshed m = load_meshed(a.scene, settings.mesh_options,
                         a.output.import(), a.output.camera);
  cli::settle_image_size(a.output, m.scene);
  const PatchMesh& mesh = m.mesh;

  cluster::EmulateConfig ec;
  static_cast<cluster::RunSettings&>(ec.run) = settings;
  ec.run.scene = m.scene;
  // An async run grants to each node as soon as it is ready: a fast node never waits for a
  // slow one's set-up. Sync rounds and the auto exchange setting (chosen from every node's
  // speed when the first grants go out) wait for all.
  const bool wait_for_all = settings.mode == cluster::Mode::sync || settings.exchange_every == cluster::kExchangeAuto;
  ec.run.min_nodes = wait_for_all ? static_cast<uint32_t>(a.nodes) : 1;
  ec.run.profile = std::move(profile);
  ec.nodes = static_cast<uint32_t>(a.nodes);
  ec.bundle_s = e.bundle_ms / 1e3;
  ec.tile_s = e.tile_ms / 1e3;
  ec.run.final_gather = final_gather_of(cli::result_options(a.output));  // the image's tiles rendered by the emulated nodes
  cluster::check_emulation(ec, mesh.size());
  auto engine = make_cl_engine(mesh, {.device = a.device, .path = a.transfer});
  std::unique_ptr<ShotEngine> shots;
  if (settings.shots_per_bundle > 0) shots = make_cl_shot_engine(mesh, a.device);
  if (!a.quiet)
    std::fprintf(stderr, "sirad emulate: %s: %zu patches, %llu bundles on %u emulated nodes%s, on %s\n", a.scene.c_str(),
                 mesh.size(), static_cast<unsigned long long>(settings.bundles), ec.nodes,
                 a.profile.empty() ? "" : fmt::format(" (profile {})", a.profile).c_str(), engine->description().c_str());
  cluster::EmulateResult r = cluster::emulate(ec, mesh, *engine, shots.get());

  Attributes attrs = cluster::run_attributes(ec.run, cluster::outcome_of(r.run), mesh, a.scene, true);
  attrs.emplace_back("sirad.emulated", std::string("virtual time"));
  attrs.emplace_back("sirad.virtual_wall_s", r.wall_s);
  attrs.emplace_back("sirad.bundle_s", r.bundle_s);
  if (r.error_estimate >= 0) attrs.emplace_back("sirad.error_estimate", r.error_estimate);
  write_outputs(a.output, out, m, r.run.radiosity, attrs, r.run.image ? &*r.run.image : nullptr);
  if (!e.nodes_csv.empty()) write_file_atomic(e.nodes_csv, cluster::nodes_csv(r));
  if (!e.timeline.empty()) write_file_atomic(e.timeline, cluster::timeline_csv(r));
  // Every node up to 32; beyond, the spread of their utilisation.
  std::vector<double> use;
  for (const auto& n : r.nodes) {
    use.push_back(n.utilisation);
    if (r.nodes.size() <= 32)
      std::printf("node %s: speed %g, %llu bundles, %u exchanges, busy %.3f s, idle %.3f s, utilisation %.1f %%\n", n.name.c_str(),
                  n.speed, static_cast<unsigned long long>(n.bundles), n.exchanges, n.busy_s, n.idle_s, 100 * use.back());
  }
  std::sort(use.begin(), use.end());
  std::printf("utilisation over %zu nodes: min %.1f %%, median %.1f %%, max %.1f %%\n", use.size(), 100 * use.front(),
              100 * use[use.size() / 2], 100 * use.back());
  std::printf("%s\n", cluster::traffic_line(r.run).c_str());
  std::printf("virtual wall time %.3f s for %llu bundles (%.3f ms per bundle at speed 1), error estimate %s; emulated in %.2f s\n",
              r.wall_s, static_cast<unsigned long long>(r.run.bundles), r.bundle_s * 1e3,
              r.error_estimate >= 0 ? fmt::format("{:.4f}", r.error_estimate).c_str() : "n/a", r.real_s);
  if (r.run.image)
    std::printf("image: %llu tiles in %.3f s of virtual time (%.3f ms a tile at speed 1)\n",
                static_cast<unsigned long long>(r.run.image_tiles), r.run.image_seconds, r.tile_s * 1e3);
  if (r.run.ended_by != "budget") std::printf("ended early: %s\n", r.run.ended_by.c_str());
  if (!r.exchange_why.empty()) std::printf("--exchange-every auto: %s\n", r.exchange_why.c_str());
  return 0;
}

int profile_table(const std::string& path, int nodes, const std::string& prefix) {
  emulation::Profile p = emulation::load_profile(path);
  std::printf("index name speed slowdown latency_ms jitter_ms up_mbit down_mbit loss disconnect_at_s reconnect_after_s\n");
  for (int i = 0; i < nodes; ++i) {
    std::string name = fmt::format("{}{}", prefix, i);
    emulation::LinkSpec l = p.for_node(static_cast<uint32_t>(i), name);
    std::printf("%d %s %g %g %g %g %g %g %g %g %g\n", i, name.c_str(), l.speed, p.slowdown(l), l.latency_ms, l.jitter_ms,
                l.up_mbit, l.down_mbit, l.loss, l.disconnect_at_s, l.reconnect_after_s);
  }
  return 0;
}

}  // namespace sirad::cli
