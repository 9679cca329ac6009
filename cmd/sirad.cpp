// sirad: the command line. `sirad render SCENE` solves a scene on one OpenCL device (or an
// embedded cluster of N nodes) and writes NAME.exr, NAME.png, NAME.ply and NAME.glb; `sirad
// emulate` runs a cluster in virtual time; `sirad devices` lists the OpenCL devices.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <set>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "cli/embedded.h"
#include "cli/run_flags.h"
#include "cluster/emulate.h"
#include "cluster/live_view.h"
#include "cluster/policy.h"
#include "cluster/profile.h"
#include "cluster/single_node.h"
#include "cluster/status.h"
#include "engine/bundle_cl.h"
#include "engine/version.h"
#include "farm/farm_client.h"
#include "io/read_solution.h"
#include "io/results.h"
#include "io/write.h"
#include "model/model.h"
#include "model/model_fit.h"
#include "proto/security.h"
#include "render/gather.h"
#include "scene/check.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "solver/reference.h"
#include "solver/solver.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace sirad {
namespace {

using cli::mesh_options_from;

struct RenderArgs {
  std::string scene;
  cli::RunFlags run;
  cli::OutputFlags output;
  std::string device;
  bool quiet = false;
  // The embedded cluster: N local nodes over ZeroMQ inproc (0: the plain single-node solver).
  int nodes = 0;
  std::string status_json;
  std::string profile;
  std::set<std::string> given;  // the flags given on the command line (long names)
};

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

// The outputs and their paths on stdout (`gathered`: the final gather's passes a cluster run
// rendered in tiles, or `image_failed` why it could not, write_results).
void write_outputs(const cli::OutputFlags& o, const std::string& out, const PatchMesh& mesh,
                   const std::vector<glm::vec3>& radiosity, Attributes attrs, const std::string& camera_from,
                   const GatherPasses* gathered = nullptr, const std::string& image_failed = {}) {
  attrs.emplace_back("sirad.camera_from", camera_from);
  ResultFiles files = write_results(out, mesh, radiosity, cli::result_options(o), attrs, gathered, image_failed);
  std::printf("camera %s (%s)\n", camera_spec(*mesh.camera).c_str(), camera_from.c_str());
  std::fputs(wrote_lines(files).c_str(), stdout);
}

// The outputs' name: --out, or the scene's file name without extension; checked before any work:
// its folder must be writable, and no output (NAME + each of `extensions`) may be the scene file.
std::string output_name(const std::string& out, const std::string& scene,
                        std::initializer_list<const char*> extensions = {".exr", ".png", ".ply", ".glb"}) {
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

// The scene `spec` names, meshed, with a camera (the scene's, else a default view of it).
struct Meshed {
  Scene scene;
  PatchMesh mesh;
  std::string camera_from;  // where the camera came from, for the outputs' line and the EXR
};
// The camera: --camera (`camera`, checked first), else the scene's, else one chosen (check_scene).
Meshed load_meshed(const std::string& spec, const MeshOptions& mesh_options, const ImportOptions& import = {},
                   const std::string& camera = "") {
  std::optional<Camera> given = cli::camera_flag(camera);
  Meshed m;
  m.scene = load_scene(spec, import);
  m.mesh = mesh_scene(m.scene, mesh_options);
  SceneCheck check = check_scene(m.scene, m.mesh, given, "--camera");
  for (const std::string& w : check.warnings) std::fprintf(stderr, "sirad: warning: %s\n", w.c_str());
  m.camera_from = check.camera_from;
  return m;
}

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
  embedded::Options eo{.nodes = a.nodes, .device = a.device};
  eo.on_done = [&](const cluster::RunResult& result) {
    reporter.finish();
    Attributes attrs = cluster::run_attributes(rc, cluster::outcome_of(result), m.mesh, a.scene, true);
    short_of = short_of_target(rc, result.ended_by, result.error_estimate);
    if (!short_of.empty())
      for (auto& [key, value] : attrs)
        if (key == "sirad.ended_by") value = short_of;
    write_outputs(a.output, out, m.mesh, result.radiosity, attrs, m.camera_from, result.image ? &*result.image : nullptr,
                  result.image_error);
  };
  embedded::Outcome o = embedded::run(rc, m.mesh, eo);
  const cluster::RunResult& result = o.result;
  std::fputs(cluster::cluster_summary(result, m.mesh.size(), o.coordinate_s).c_str(), stdout);
  return finish_line(result.ended_by, short_of, static_cast<int64_t>(result.bundles));
}

int render(RenderArgs a) {
  // Check everything cheap before any work: flags, output place, scene, device.
  if (!a.profile.empty() && a.nodes == 0) fail("--profile {}: emulation needs a cluster (--nodes N)", a.profile);
  if (a.nodes == 0) {
    std::vector<std::string> cluster_only = cli::cluster_flag_names();
    cluster_only.push_back("--status-json");
    refuse_given(a, cluster_only, "has no effect on one node: it is a cluster setting (--nodes N)");
  }
  const cluster::RunSettings settings = cli::settings_from(a.run, a.given);
  if (a.nodes > 0) {
    if (std::string why = cluster::target_error_problem(settings); !why.empty()) fail("{}", why);
  }
  std::optional<emulation::Profile> profile;
  if (!a.profile.empty()) profile = emulation::load_profile(a.profile);
  if (settings.target_error > 0 && a.nodes == 0 && settings.rule != UpdateRule::chain)
    fail("--target-error on one node needs --rule chain (its batch means assume the chain's estimates)");
  std::string out = output_name(a.output.out, a.scene);
  Meshed m = load_meshed(a.scene, settings.mesh_options,
                         a.output.import(), a.output.camera);
  cli::settle_image_size(a.output, m.scene);
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
  auto engine = make_cl_engine(mesh, {.device = a.device});
  SolverOptions so = cluster::solver_options(settings, mesh, 0);
  so.track_error = settings.target_error > 0 || mesh.size() <= kTrackErrorMaxPatches;
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
  write_outputs(a.output, out, mesh, solver.estimate(), attrs, m.camera_from);
  std::printf("%s\n", cluster::summary_line(mesh.size(), static_cast<uint64_t>(done), solver.grid(), 0, seconds, solver.crossings(),
                                            fmt::format(", error estimate {}", error >= 0 ? fmt::format("{:.4f}", error) : "n/a"))
                          .c_str());
  return finish_line(ended_by, short_of, done);
}

struct EmulateArgs {
  RenderArgs run;
  double bundle_ms = 0;
  std::string nodes_csv, timeline;
};

// `sirad emulate`: the virtual-time cluster (cluster/emulate.h) on this machine's device.
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
  std::string out = output_name(a.output.out, a.scene);
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
  cluster::check_emulation(ec, mesh.size());
  auto engine = make_cl_engine(mesh, {.device = a.device});
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
  write_outputs(a.output, out, mesh, r.run.radiosity, attrs, m.camera_from);
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
  if (r.run.ended_by != "budget") std::printf("ended early: %s\n", r.run.ended_by.c_str());
  if (!r.exchange_why.empty()) std::printf("--exchange-every auto: %s\n", r.exchange_why.c_str());
  return 0;
}

// The links a profile gives nodes 0..N-1 (named PREFIX0, PREFIX1, ...), one row each: for
// people checking a profile and for deploy/netns-cluster.sh (tc rates per node).
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

// `sirad model`: the paper's cost and error model (model/model.h) for one setup, or swept over
// processors, exchange periods or fractions; CSV on stdout, then the exchange period that
// maximises the effective sample number.
struct ModelArgs {
  model::Setup setup;
  model::Costs costs;
  model::Scene scene_params;
  double time = 60.0;
  std::string sweep = "none";
  uint64_t max = 16;
  std::string scene;                // fit a, sigma_1 / C and T_i on this scene's real bundles
  std::optional<int64_t> patches;
  std::string device;
  std::string from_run;             // a --status-json file: P, I, S, T, T_i and T_e from a real run
  bool time_given = false;
  double time_to = 0;               // > 0: also the time the model needs to reach this error
  std::string profile;              // T_e from this profile's links for a state of state_patches
  std::optional<int64_t> state_patches;
  CLI::Option* t_exchange_flag = nullptr;
};

CLI::App* add_model_command(CLI::App& app, ModelArgs& m) {
  auto* cmd = app.add_subcommand("model", "The paper's cost and error model: predicted error and effective samples (CSV)");
  cmd->add_option("--processors", m.setup.processors, "P")->check(CLI::Range(1, 1000000))->capture_default_str();
  cmd->add_option("--exchange-every", m.setup.exchange_every, "I (0: never)")->check(CLI::Range(uint64_t{0}, uint64_t{1} << 40))->capture_default_str();
  cmd->add_option("--fraction", m.setup.fraction, "S in (0, 1]")->check(cli::finite_in(1e-9, 1.0))->capture_default_str();
  cmd->add_option("--contraction", m.scene_params.contraction, "a in [0, 1)")->check(cli::finite_in(0.0, 0.999999))->capture_default_str();
  cmd->add_option("--sigma", m.scene_params.sigma_ratio, "sigma_1 / C")->check(cli::positive())->capture_default_str();
  cmd->add_option("--t-iteration", m.costs.t_iteration, "T_i, seconds per iteration")->check(cli::positive())->capture_default_str();
  m.t_exchange_flag = cmd->add_option("--t-exchange", m.costs.t_exchange, "T_e, seconds per exchange with one processor")
                          ->check(cli::non_negative())
                          ->capture_default_str();
  cmd->add_option("--time", m.time, "T, seconds")->check(cli::positive())->capture_default_str();
  cmd->add_option("--sweep", m.sweep, "none, processors (P = 1..max), period (I = 1..max) or fraction (S = k / max)")
      ->check(CLI::IsMember({"none", "processors", "period", "fraction"}))->capture_default_str();
  cmd->add_option("--max", m.max, "Sweep range, and the largest I searched for the best")->check(CLI::Range(uint64_t{1}, uint64_t{1000000}))->capture_default_str();
  cmd->add_option("--scene", m.scene, "Fit the contraction, sigma_1 / C and T_i on this scene's bundles (replacing those flags)");
  cmd->add_option("--patches", m.patches, "Mesh the fitted scene to about this many patches (default 10000)")
      ->check(CLI::Range(int64_t{1}, int64_t{1} << 31));
  cmd->add_option("--device", m.device, "OpenCL device for the fit");
  cmd->add_option("--time-to", m.time_to, "Also print the time each setup needs to reach this relative error (column time_to_error)")
      ->check(cli::finite_in(1e-9, 1e9));
  cmd->add_option("--from-run", m.from_run,
                  "A run's --status-json file: its P, I, S, time, T_i (busy / bundles) and T_e (idle / exchanges) are the setup");
  cmd->add_option("--profile", m.profile,
                  "T_e from this emulation profile's links (the nodes' and the coordinator's) for a sync exchange of "
                  "--state-patches patches (or the --scene's)");
  cmd->add_option("--state-patches", m.state_patches, "With --profile: the patches of the state exchanged")
      ->check(CLI::Range(int64_t{1}, int64_t{1} << 31));
  return cmd;
}

// The setup and costs of a real run from its status file: P = the nodes that ran bundles, its
// I and S, T = its elapsed time (unless --time), T_i = busy time / bundles over the nodes, and
// T_e = the nodes' idle time (waiting for the next grant: in sync mode the exchange barrier)
// over exchanges x P x S, as equation (1) charges P S T_e per exchange. Without idle time
// (async mode, or exchanges only at the end) T_e stays the flag's.
void apply_run(ModelArgs& m) {
  cluster::Status st = cluster::read_status(m.from_run);
  uint32_t processors = 0;
  uint64_t bundles = 0, exchanges = 0;
  double busy = 0, idle = 0;
  for (const auto& n : st.nodes) {
    if (n.bundles == 0) continue;
    ++processors;
    bundles += n.bundles;
    exchanges += n.exchanges;
    busy += n.busy_s;
    idle += n.idle_s;
  }
  if (processors == 0 || !(busy > 0)) fail("{}: no node of the run reported bundles and busy time", m.from_run);
  m.setup.processors = processors;
  m.setup.exchange_every = st.exchange_every;
  m.setup.fraction = st.exchange_fraction;
  if (!m.time_given) m.time = st.elapsed_s;
  m.costs.t_iteration = busy / static_cast<double>(bundles);
  const bool measured = exchanges > 0 && idle > 0;
  if (measured) m.costs.t_exchange = idle / (static_cast<double>(exchanges) * processors * st.exchange_fraction);
  std::printf("# from the run %s: P = %u, I = %llu, S = %g (%s, %s), T = %.3f s, T_i = %.6f s (busy / bundles), "
              "T_e = %.6f s (%s)\n",
              m.from_run.c_str(), processors, static_cast<unsigned long long>(st.exchange_every), st.exchange_fraction,
              st.mode.c_str(), st.topology.c_str(), m.time, m.costs.t_iteration, m.costs.t_exchange,
              measured ? "idle / (exchanges x P x S)" : "no exchange waits in the run: --t-exchange");
}

// T_e of a sync exchange on the profile's links, as --exchange-every auto charges it
// (cluster/policy.h auto_exchange): P S T_e = max(S e, P S c), e the slowest of the P nodes'
// links (state up and back down), c the coordinator's link per node's state. A star and a ring
// both pass every state through the coordinator (PROTOCOL.md section 3.3): the same cost.
void apply_profile(ModelArgs& m, std::size_t patches) {
  emulation::Profile profile = emulation::load_profile(m.profile);
  double e = 0;
  for (uint32_t n = 0; n < m.setup.processors; ++n) {
    emulation::LinkSpec spec = profile.for_node(n, fmt::format("node-{}", n));
    e = std::max(e, cluster::exchange_seconds(patches, &spec));
  }
  const double c = profile.coordinator ? cluster::coordinator_seconds(patches, *profile.coordinator) : 0.0;
  m.costs.t_exchange = std::max(e / m.setup.processors, c);
  std::printf("# T_e from %s for %zu patches: the nodes' links %.6f s each (side by side), the coordinator's %s; "
              "T_e = %.6f s\n",
              m.profile.c_str(), patches, e, profile.coordinator ? fmt::format("{:.6f} s per node (in turn)", c).c_str() : "not modelled",
              m.costs.t_exchange);
}

int model_table(ModelArgs m) {
  if (!m.profile.empty()) {
    if (!m.from_run.empty()) fail("--profile: --from-run measured T_e already; give one of them");
    if (m.t_exchange_flag->count() > 0) fail("--profile: it sets T_e; --t-exchange would be ignored");
    if (!m.state_patches && m.scene.empty()) fail("--profile needs the state's size: --state-patches N or --scene");
    if (m.sweep == "processors") fail("--profile: T_e depends on P, so it cannot sweep the processors");
  } else if (m.state_patches) {
    fail("--state-patches: only with --profile");
  }
  if (!m.from_run.empty()) apply_run(m);
  if (!m.scene.empty()) {
    PatchMesh mesh = mesh_scene(load_scene(m.scene), mesh_options_from(m.patches, std::nullopt));
    auto engine = make_cl_engine(mesh, {.device = m.device});
    model::SceneFit fit = model::fit_scene(mesh, *engine);
    m.scene_params.contraction = std::min(fit.contraction, 0.999);
    m.scene_params.sigma_ratio = fit.sigma_ratio;
    if (m.from_run.empty()) m.costs.t_iteration = fit.t_iteration;  // a run's own T_i is the better one
    std::printf("# fitted on %s (%zu patches, %llu bundles on %s): contraction a = %.4f +- %.4f, sigma_1 / C = %.4f, "
                "T_i = %.6f s\n",
                m.scene.c_str(), mesh.size(), static_cast<unsigned long long>(fit.bundles), engine->description().c_str(),
                fit.contraction, fit.contraction_se, fit.sigma_ratio, fit.t_iteration);
    if (!m.profile.empty() && !m.state_patches) apply_profile(m, mesh.size());
  }
  if (!m.profile.empty() && m.state_patches) apply_profile(m, static_cast<std::size_t>(*m.state_patches));
  model::check(m.setup);
  model::check(m.costs);
  model::check(m.scene_params);
  std::printf("processors,exchange_every,fraction,contraction,sigma_ratio,t_iteration,t_exchange,time,iterations,phases,"
              "relative_error,log_effective_samples,bias,sd%s\n", m.time_to > 0 ? ",time_to_error" : "");
  auto row = [&](const model::Setup& s) {
    model::Prediction p = model::predict(m.time, s, m.costs, m.scene_params);
    std::printf("%u,%llu,%g,%g,%g,%g,%g,%g,%llu,%llu,%.6g,%.6f,%.6g,%.6g", s.processors, static_cast<unsigned long long>(s.exchange_every),
                s.fraction, m.scene_params.contraction, m.scene_params.sigma_ratio, m.costs.t_iteration, m.costs.t_exchange, m.time,
                static_cast<unsigned long long>(p.iterations), static_cast<unsigned long long>(p.phases), p.relative_error,
                p.log_effective, p.bias, p.sd);
    if (m.time_to > 0) std::printf(",%.6g", model::time_to_error(m.time_to, s, m.costs, m.scene_params));
    std::printf("\n");
  };
  for (uint64_t k = 1; k <= (m.sweep == "none" ? 1 : m.max); ++k) {
    model::Setup s = m.setup;
    if (m.sweep == "processors") s.processors = static_cast<uint32_t>(k);
    if (m.sweep == "period") s.exchange_every = k;
    if (m.sweep == "fraction") s.fraction = static_cast<double>(k) / static_cast<double>(m.max);
    row(s);
  }
  model::Setup s = m.setup;
  std::printf("# best exchange period for the effective sample number (I = 1..%llu): %llu\n",
              static_cast<unsigned long long>(m.max),
              static_cast<unsigned long long>(model::best_period(m.time, s, m.costs, m.scene_params.contraction, m.max)));
  return 0;
}

// `sirad reference SCENE`: the independent reference solver (solver/reference.h). Writes NAME.exr,
// .png, .ply like `render`, plus NAME.ref.csv (per-patch B, D and their standard errors).
struct ReferenceArgs {
  std::string scene;
  std::optional<int64_t> patches;
  std::optional<double> max_edge;
  ReferenceOptions options;
  cli::OutputFlags output;
  bool quiet = false;
};

CLI::App* add_reference_command(CLI::App& app, ReferenceArgs& r) {
  auto* cmd = app.add_subcommand("reference", "Independent reference solution (Embree rays, exact direct light); "
                                              "write NAME.exr, .png, .ply and NAME.ref.csv");
  cli::add_scene_argument(cmd, r.scene);
  cmd->add_option("--patches", r.patches, "Mesh to about this many patches (default 10000)")
      ->check(CLI::Range(int64_t{1}, int64_t{1} << 31));
  cmd->add_option("--max-edge", r.max_edge, "Mesh so no patch edge is longer than this")->check(cli::positive());
  cmd->add_option("--rays", r.options.rays_per_patch, "Cosine-distributed rays per patch (all batches)")
      ->check(CLI::Range(1, 1 << 24))->capture_default_str();
  cmd->add_option("--light-samples", r.options.light_samples,
                  "Direct-light points per patch (all batches), each with one shadow ray per emitter triangle")
      ->check(CLI::Range(1, 1 << 24))->capture_default_str();
  cmd->add_option("--batches", r.options.batches, "Independent batches for the standard error")
      ->check(CLI::Range(2, 1024))->capture_default_str();
  cmd->add_option("--seed", r.options.seed, "Seed")->capture_default_str();
  cmd->add_option("--threads", r.options.threads, "Threads (0: all cores)")->check(CLI::Range(0, 1024))->capture_default_str();
  cli::add_output_flags(cmd, r.output);
  cmd->add_flag("-q,--quiet", r.quiet, "No progress output");
  return cmd;
}

int reference(const ReferenceArgs& r) {
  MeshOptions mesh_options = mesh_options_from(r.patches, r.max_edge);
  if (r.options.rays_per_patch < r.options.batches)
    fail("--rays {} is below --batches {}", r.options.rays_per_patch, r.options.batches);
  if (r.options.light_samples < r.options.batches)
    fail("--light-samples {} is below --batches {}", r.options.light_samples, r.options.batches);
  std::string out = output_name(r.output.out, r.scene, {".exr", ".png", ".ply", ".glb", ".ref.csv"});
  auto [scene, mesh, camera_from] = load_meshed(
      r.scene, mesh_options, r.output.import(), r.output.camera);
  cli::OutputFlags output = r.output;
  cli::settle_image_size(output, scene);
  if (!r.quiet)
    std::fprintf(stderr, "sirad: %s: %zu patches, reference with %d rays and %d light samples per patch, %d batches\n",
                 r.scene.c_str(), mesh.size(), r.options.rays_per_patch, r.options.light_samples, r.options.batches);
  ReferenceSolution s = solve_reference(mesh, r.options);
  std::vector<glm::vec3> radiosity(mesh.size());
  for (std::size_t j = 0; j < mesh.size(); ++j) radiosity[j] = glm::vec3(s.radiosity[j]);
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
  };
  write_outputs(output, out, mesh, radiosity, attrs, camera_from);
  const std::string csv = out + ".ref.csv";
  write_reference(csv, mesh, s, r.options);
  std::printf("wrote %s\n", std::filesystem::absolute(csv).c_str());
  std::printf("patches %zu, rays %llu, %.2f s, %.3g rays/s, %d sweeps%s, mean relative SE %.3g%%\n", mesh.size(),
              static_cast<unsigned long long>(s.rays), s.seconds, static_cast<double>(s.rays) / s.seconds, s.iterations,
              s.converged ? "" : " (not converged: iteration cap)", 100.0 * mean_relative_se(mesh, s));
  return 0;
}

// sirad image SOLUTION: a final gather (render/gather.h) of a solution read back from the PLY or
// glTF sirad wrote (io/read_solution.h).
struct ImageArgs {
  std::string solution, camera, cameras, out;
  GatherOptions gather;
  float exposure = 0.0f;
  bool quiet = false;
};

CLI::App* add_image_command(CLI::App& app, ImageArgs& a) {
  auto* cmd = app.add_subcommand("image", "Image a solved scene (the PLY or glb sirad wrote) by a final gather: direct light traced, "
                                          "indirect from the solution; write NAME.exr (passes direct, indirect) and NAME.png");
  cmd->add_option("solution", a.solution, "The solution: the .ply or .glb written by sirad render, reference or a coordinator")->required();
  auto* camera = cmd->add_option("--camera", a.camera,
                                 "The view: \"eye X Y Z look X Y Z up X Y Z fov DEG\" (default: the solution's camera)");
  cmd->add_option("--cameras", a.cameras,
                  "A walkthrough: one view per line (as --camera; blank lines and # comments skipped), written NAME-0001 ...")
      ->excludes(camera);
  a.gather.width = a.gather.height = 0;  // settled from the solution's camera (cli::settle_image_size)
  cmd->add_option("--width", a.gather.width, "Image width (default: the camera's aspect times the height)")->check(CLI::Range(1, kMaxImageSide));
  cmd->add_option("--height", a.gather.height, "Image height (default: 512, or the width over the camera's aspect)")
      ->check(CLI::Range(1, kMaxImageSide));
  cmd->add_option("--spp", a.gather.spp, "Samples per pixel (each: a primary ray, an emitter sample, a gather ray)")
      ->check(CLI::Range(1, 65536))->capture_default_str();
  cmd->add_option("--seed", a.gather.seed, "Seed")->capture_default_str();
  cmd->add_option("--threads", a.gather.threads, "Threads (0: all cores)")->check(CLI::Range(0, 1024))->capture_default_str();
  cmd->add_option("--exposure", a.exposure, "PNG exposure in stops")->check(cli::finite_in(-64.0, 64.0));
  cmd->add_option("--out", a.out, "Output name: NAME.exr and NAME.png (default: the solution's name with -image)");
  cmd->add_flag("-q,--quiet", a.quiet, "No progress output");
  return cmd;
}

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

// The flags of a run, shared by `render` and `emulate` (the cluster flags: with --nodes).
void add_run_options(CLI::App* cmd, RenderArgs& r) {
  cli::add_scene_argument(cmd, r.scene);
  cli::add_run_flags(cmd, r.run);
  cli::add_output_flags(cmd, r.output);
  cmd->add_option("--device", r.device, "OpenCL device: P:D, or part of its name (env SIRAD_DEVICE)");
  cmd->add_flag("-q,--quiet", r.quiet, "No progress output");
}

// sirad keygen NAME: a CURVE key pair (proto/security.h); the public key goes to the other side
// (a node's into the coordinator's allow list, the coordinator's to every node).
int keygen(const std::string& name) {
  check_output_name(name, "keygen NAME");
  proto::KeyPair keys = proto::generate_keypair();
  proto::write_keypair(name, keys);
  std::printf("wrote %s.key\nwrote %s.key_secret (mode 0600; keep it on this machine)\n"
              "allow-list line: %s %s\n",
              name.c_str(), name.c_str(), keys.public_key.c_str(), std::filesystem::path(name).filename().c_str());
  return 0;
}

int run(int argc, char** argv) {
  CLI::App app{"sirad: diffuse global illumination by stochastic iteration with bundles of parallel lines"};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "Every subcommand's options too (what the man page shows)");
  app.set_version_flag("--version", [] { return version_text("sirad"); }, "Version, git commit and OpenCL platforms");
  RenderArgs r;
  auto* render_cmd = app.add_subcommand("render", "Solve a scene on one OpenCL device (or N embedded nodes); write NAME.exr, .png, .ply, .glb");
  add_run_options(render_cmd, r);
  render_cmd->add_option("--nodes", r.nodes, "Embedded cluster: N local nodes over ZeroMQ inproc (0: single node)")
      ->check(CLI::Range(0, 64));
  render_cmd->add_option("--status-json", r.status_json, "With --nodes: rewrite this file with the run's status every second");
  render_cmd->add_option("--profile", r.profile, "With --nodes: network emulation profile (YAML; nodes are named local-0, local-1, ...)");
  EmulateArgs e;
  auto* emulate_cmd = app.add_subcommand(
      "emulate", "Run a cluster of N nodes in virtual time on this machine (real bundles, emulated clocks and links); write NAME.exr, .png, .ply");
  add_run_options(emulate_cmd, e.run);
  emulate_cmd->add_option("--nodes", e.run.nodes, "Emulated nodes (default: the profile's node entries)")
      ->check(CLI::Range(1, 4096));
  emulate_cmd->add_option("--profile", e.run.profile, "Emulation profile (YAML): speeds and links; nodes are named emu-0, emu-1, ...");
  emulate_cmd->add_option("--bundle-ms", e.bundle_ms,
                          "Milliseconds of one bundle at speed 1 (default: measured before the run; fix it for a reproducible timeline)")
      ->check(cli::positive());
  emulate_cmd->add_option("--nodes-csv", e.nodes_csv, "Write the per-node figures (bundles, busy, idle, utilisation) as CSV");
  emulate_cmd->add_option("--timeline", e.timeline, "Write the virtual timeline (every grant, report, update, stop) as CSV");
  ReferenceArgs ref_args;
  auto* reference_cmd = add_reference_command(app, ref_args);
  ModelArgs model_args;
  auto* model_cmd = add_model_command(app, model_args);
  ImageArgs image_args;
  auto* image_cmd = add_image_command(app, image_args);
  app.add_subcommand("devices", "List the OpenCL devices");
  std::string profile_path, profile_prefix = "local-";
  int profile_nodes = 4;
  std::string keygen_name;
  auto* keygen_cmd = app.add_subcommand("keygen", "Make a CURVE key pair for a TCP cluster: NAME.key (public) and NAME.key_secret (mode 0600)");
  keygen_cmd->add_option("name", keygen_name, "Path and base name of the two files")->required();
  auto* profile_cmd = app.add_subcommand("profile", "Check an emulation profile; print the link of each node");
  profile_cmd->add_option("file", profile_path, "Profile (YAML)")->required();
  profile_cmd->add_option("--nodes", profile_nodes, "Nodes to list")->check(CLI::Range(1, 4096))->capture_default_str();
  profile_cmd->add_option("--name-prefix", profile_prefix, "Node names are PREFIX0, PREFIX1, ...")->capture_default_str();

  // The farm's client (farm/farm_client.h).
  cli::FarmAddress farm;
  auto add_farm = [&](CLI::App* cmd, bool token) {
    cmd->add_option("--farm", farm.farm, "The farm: http://HOST:PORT, or its folder on this machine")->required();
    if (token)
      cmd->add_option("--token-file", farm.token_file, "The farm's token (default: SIRAD_FARM_TOKEN, or the farm folder's)");
  };
  std::string submit_scene, submit_name;
  int submit_priority = 0;
  auto* submit_cmd = app.add_subcommand("submit", "Queue a job on a farm (sirad-coordinator --serve): SCENE and its run and output flags, and --min-nodes N, --max-nodes N (the most nodes it takes; 0: every node)");
  cli::add_scene_argument(submit_cmd, submit_scene);
  add_farm(submit_cmd, true);
  submit_cmd->add_option("--priority", submit_priority, "Higher runs first (default 0)")->check(CLI::Range(-1000000, 1000000));
  submit_cmd->add_option("--name", submit_name, "The job's name, and its outputs' (default: the scene's)");
  submit_cmd->allow_extras();  // the job's own flags, checked against the run and output flags
  auto* jobs_cmd = app.add_subcommand("jobs", "List a farm's jobs and their progress");
  add_farm(jobs_cmd, false);
  uint64_t cancel_id = 0;
  auto* cancel_cmd = app.add_subcommand("cancel", "Cancel a farm's job (a running one stops at its checkpoint)");
  cancel_cmd->add_option("id", cancel_id, "The job's id (sirad jobs)")->required();
  add_farm(cancel_cmd, true);

  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --help-all, --version
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "sirad: error: %s (see sirad --help)\n", e.what());
    return 2;
  }
  auto given = [](const CLI::App* cmd) { return cli::given_flags(cmd); };
  if (render_cmd->parsed()) {
    r.given = given(render_cmd);
    return render(r);
  }
  if (emulate_cmd->parsed()) {
    e.run.given = given(emulate_cmd);
    return emulate(e);
  }
  if (reference_cmd->parsed()) return reference(ref_args);
  if (image_cmd->parsed()) return image(image_args);
  if (model_cmd->parsed()) {
    model_args.time_given = model_cmd->count("--time") > 0;
    return model_table(model_args);
  }
  if (profile_cmd->parsed()) return profile_table(profile_path, profile_nodes, profile_prefix);
  if (keygen_cmd->parsed()) return keygen(keygen_name);
  if (submit_cmd->parsed()) return cli::submit_job(farm, submit_scene, submit_cmd->remaining(), submit_name, submit_priority);
  if (jobs_cmd->parsed()) return cli::list_jobs(farm);
  if (cancel_cmd->parsed()) return cli::cancel_job(farm, cancel_id);
  return devices();
}

}  // namespace
}  // namespace sirad

int main(int argc, char** argv) {
  try {
    return sirad::run(argc, argv);
  } catch (const sirad::Error& e) {
    std::fprintf(stderr, "sirad: error: %s\n", e.what());
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "sirad: error: out of memory\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad: error: %s\n", e.what());
  }
  return 1;
}
