// sirad-coordinator: serves one run of a scene to the nodes that connect, then writes its
// outputs (NAME.exr, NAME.png, NAME.ply, NAME.glb). The run flags are sirad render's
// (cmd/run_flags.h); the rest are the coordinator's own: --listen, --min-nodes, security,
// liveness, checkpoints and --resume, status and ledger files. `sirad-coordinator --help`.
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <set>

#include <CLI/CLI.hpp>

#include "core/scene_check.h"
#include "cluster/checkpoint.h"
#include "cmd/log_flags.h"
#include "cmd/run_flags.h"
#include "coordinator/coordinator.h"
#include "cluster/live_view.h"
#include "core/atomic_file.h"
#include "core/bundle.h"
#include "core/error.h"
#include "core/results.h"
#include "core/version.h"
#include "proto/security.h"
#include "proto/transport.h"

using namespace sirad;

namespace {
std::atomic<bool> interrupted{false};
void on_signal(int) { interrupted = true; }
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"sirad-coordinator: orchestrates sirad nodes solving one scene"};
  app.set_version_flag("--version", [] { return sirad::version_text("sirad-coordinator"); }, "Version, git commit and OpenCL platforms");
  std::string scene_spec, listen = "tcp://*:5555", endpoint_file, status_json, profile, curve_secret, allow_file, ledger,
                          checkpoint, resume;
  cli::RunFlags run;
  cli::OutputFlags output;
  double checkpoint_every = 10, timeout = 0;
  int min_nodes = 1, heartbeat_ms = 1000, liveness = 3;
  bool check_config = false, quiet = false, network_bandwidth = false, insecure = false;
  cli::add_scene_argument(&app, scene_spec);
  app.add_option("--listen", listen, "ZeroMQ endpoint to bind")->capture_default_str();
  const std::vector<std::string> run_flags = cli::add_run_flags(&app, run);
  cli::add_output_flags(&app, output);
  app.add_option("--min-nodes", min_nodes, "Nodes ready before the first grant")->check(CLI::Range(1, 4096))->capture_default_str();
  app.add_option("--endpoint-file", endpoint_file, "Write the bound endpoint here (for scripts: tcp://*:0 picks a port)");
  app.add_option("--status-json", status_json, "Rewrite this file with the run's status every second");
  app.add_option("--ledger", ledger, "At the end, write which node ran which bundle indices (CSV: node,name,first,last)");
  app.add_option("--timeout", timeout, "Fail if the run takes longer (seconds; 0: never)")->check(cli::non_negative());
  app.add_option("--profile", profile, "Network emulation profile (YAML; see deploy/profiles/)");
  app.add_option("--heartbeat-ms", heartbeat_ms, "Heartbeat interval")->check(CLI::Range(10, 60000))->capture_default_str();
  app.add_option("--liveness", liveness, "Heartbeats a node may miss before it is dead")->check(CLI::Range(1, 100))->capture_default_str();
  app.add_flag("--bandwidth-by-network", network_bandwidth,
               "The network limits bandwidth (tc); do not emulate the profile's up/down rates");
  auto* secret_opt = app.add_option("--curve-secret", curve_secret,
                                    "This coordinator's CURVE secret key file (NAME.key_secret from sirad keygen; mode 0600)");
  auto* allow_opt = app.add_option("--allow", allow_file, "Allow list: the node public keys admitted, one Z85 key (and a name) per line");
  secret_opt->needs(allow_opt);
  allow_opt->needs(secret_opt);
  app.add_flag("--insecure", insecure, "Over TCP without CURVE: no authentication, no encryption (says so on start)");
  app.add_option("--checkpoint", checkpoint,
                 "Write the run's checkpoint here (atomically) every --checkpoint-every seconds and on SIGTERM/SIGINT");
  app.add_option("--checkpoint-every", checkpoint_every, "Seconds between checkpoints")
      ->check(CLI::Range(0.1, 86400.0))->capture_default_str();
  app.add_option("--resume", resume,
                 "Continue the run of this checkpoint (its settings; the same scene), checkpointing to it unless --checkpoint");
  app.add_flag("--check-config", check_config, "Check the flags, scene, profile and output place; run nothing");
  app.add_flag("-q,--quiet", quiet, "No progress view");
  cli::LogFlags log_flags;
  log_flags.add(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::Success& e) {  // --help, --version
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "sirad-coordinator: error: %s (see sirad-coordinator --help)\n", e.what());
    return 2;
  }
  try {
    log_flags.apply();
    const std::set<std::string> given = cli::given_flags(&app);
    std::string out = output.out.empty() ? std::filesystem::path(scene_spec).stem().string() : output.out;
    check_output_name(out, "--out");
    if (!ledger.empty()) check_file_name(ledger, "--ledger");
    if (!checkpoint.empty()) check_file_name(checkpoint, "--checkpoint");
    if (!status_json.empty()) check_file_name(status_json, "--status-json");
    cluster::RunConfig rc;
    std::optional<wire::Checkpoint> resumed;
    if (!resume.empty()) {
      // The run's settings are the checkpoint's: a flag that would change them is a mistake.
      for (const std::string& flag : run_flags)
        if (given.count(flag)) fail("{} with --resume: a resumed run keeps the checkpoint's settings", flag);
      resumed = cluster::read_checkpoint(resume);
      static_cast<cluster::RunSettings&>(rc) = cluster::settings_of(*resumed);
      rc.resume = &*resumed;
      if (checkpoint.empty()) checkpoint = resume;
    } else {
      static_cast<cluster::RunSettings&>(rc) = cli::settings_from(run, given);
      if (std::string why = cluster::target_error_problem(rc); !why.empty()) fail("{}", why);
    }
    rc.scene = load_scene(scene_spec, {.skip_degenerate = output.skip_degenerate, .two_sided = output.two_sided});
    rc.min_nodes = static_cast<uint32_t>(min_nodes);
    rc.timeout_s = timeout;
    rc.heartbeat_ms = static_cast<uint32_t>(heartbeat_ms);
    rc.liveness = static_cast<uint32_t>(liveness);
    if (!profile.empty()) rc.profile = emulation::load_profile(profile);
    cluster::check_real_run(rc);
    rc.emulate_bandwidth = !network_bandwidth;
    rc.checkpoint = checkpoint;
    rc.checkpoint_every_s = checkpoint_every;
    PatchMesh mesh = mesh_scene(rc.scene, rc.mesh_options);
    const SceneCheck check = check_scene(rc.scene, mesh, cli::camera_flag(output.camera), "--camera");
    if (resumed && resumed->run().scene_hash() != mesh.hash)
      fail("{}: the checkpoint is of scene {}; {} meshes to {} (the same file, --patches and --two-sided?)", resume,
           resumed->run().scene_hash(), scene_spec, mesh.hash);
    for (const std::string& w : check.warnings) std::fprintf(stderr, "sirad-coordinator: warning: %s\n", w.c_str());
    proto::check_endpoint("--listen", listen, true);
    proto::check_security(listen, !curve_secret.empty(), insecure, "--curve-secret and --allow");
    std::optional<proto::KeyPair> keys;
    proto::AllowList allow;
    if (!curve_secret.empty()) {
      keys = proto::load_secret_key(curve_secret);
      allow = proto::load_allow_list(allow_file);
      if (allow.empty()) fail("{}: the allow list admits no node", allow_file);
    }
    if (check_config) {
      std::printf("sirad-coordinator: config ok: %s, %zu patches, %lld bundles, exchange every %s, S %g, %s, %s%s%s\n",
                  scene_spec.c_str(), mesh.size(), static_cast<long long>(rc.bundles), cluster::exchange_every_name(rc.exchange_every).c_str(),
                  rc.fraction, rc.topology == cluster::Topology::star ? "star" : "ring", rc.mode == cluster::Mode::sync ? "sync" : "async",
                  profile.empty() ? "" : ", profile ", profile.c_str());
      return 0;
    }
    cluster::StatusReporter reporter(quiet, status_json);
    rc.status_every_s = 0.25;
    rc.status = std::ref(reporter);

    zmq::context_t context;
    std::optional<proto::ZapHandler> zap;  // before the bind: libzmq admits everyone without one
    if (keys) zap.emplace(context, allow);
    zmq::socket_t router(context, zmq::socket_type::router);
    router.set(zmq::sockopt::linger, 0);
    proto::harden(router, proto::max_frame_bytes(mesh.size()));
    if (keys) proto::make_curve_server(router, *keys);
    try {
      router.bind(listen);
    } catch (const zmq::error_t& e) {
      fail("--listen {}: {}", listen, e.what());
    }
    std::string bound = router.get(zmq::sockopt::last_endpoint);
    logging::write(logging::Level::info, "sirad-coordinator",
                   fmt::format("{}: {} patches, {} bundles; listening on {}{}", scene_spec, mesh.size(), rc.bundles, bound,
                               keys ? fmt::format(" (CURVE, {} node keys allowed)", allow.size()) : ""),
                   {{"event", "listening"}, {"scene", scene_spec}, {"patches", mesh.size()}, {"bundles", rc.bundles},
                    {"endpoint", bound}, {"version", kVersion}});
    if (insecure) logging::write(logging::Level::warn, "sirad-coordinator", proto::insecure_warning(bound), {{"event", "insecure"}});
    if (!endpoint_file.empty()) {
      AtomicFile f(endpoint_file);
      f.write(bound.data(), bound.size());
      f.commit();
    }
    std::signal(SIGINT, on_signal);
    std::signal(SIGTERM, on_signal);
    rc.interrupt = &interrupted;
    auto start = std::chrono::steady_clock::now();
    cluster::RunResult result = cluster::coordinate(router, rc, mesh);
    reporter.finish();
    double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ResultOptions ro;
    ro.width = output.width;
    ro.height = output.height;
    ro.exposure = output.exposure;
    ro.shading = output.flat ? Shading::flat : Shading::gouraud;
    ResultFiles files = write_results(
        out, mesh, result.radiosity, ro,
        cluster::run_attributes(rc, cluster::outcome_of(result), mesh, scene_spec, true));
    std::fputs(wrote_lines(files).c_str(), stdout);
    if (!ledger.empty()) {
      write_file_atomic(ledger, cluster::ledger_csv(result));
      std::printf("wrote %s\n", std::filesystem::absolute(ledger).c_str());
    }
    std::fputs(cluster::cluster_summary(result, mesh.size(), seconds).c_str(), stdout);
    if (result.ended_by != "budget") std::printf("ended early: %s\n", result.ended_by.c_str());
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "sirad-coordinator: error: out of memory\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sirad-coordinator: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
